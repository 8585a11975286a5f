"""Deprecated alias of :mod:`pmaccuracy.model.manipulator` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import manipulator as _module

warnings.warn("pmaccuracy.geometry moved to pmaccuracy.model.manipulator; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
