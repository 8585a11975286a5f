"""Deprecated alias of :mod:`pmaccuracy.model.legs` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import legs as _module

warnings.warn("pmaccuracy.legs moved to pmaccuracy.model.legs; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
