"""Deprecated alias of :mod:`pmaccuracy.numerics.screws` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .numerics import screws as _module

warnings.warn("pmaccuracy.screws moved to pmaccuracy.numerics.screws; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
