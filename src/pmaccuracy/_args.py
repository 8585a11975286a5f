"""Deprecated alias of :mod:`pmaccuracy.io.resolve` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .io import resolve as _module

warnings.warn("pmaccuracy._args moved to pmaccuracy.io.resolve; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
