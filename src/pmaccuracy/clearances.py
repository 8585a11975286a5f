"""Deprecated alias of :mod:`pmaccuracy.model.clearances` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import clearances as _module

warnings.warn("pmaccuracy.clearances moved to pmaccuracy.model.clearances; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
