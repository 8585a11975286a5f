"""Deprecated alias of :mod:`pmaccuracy.model.serial` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import serial as _module

warnings.warn("pmaccuracy.serial moved to pmaccuracy.model.serial; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
