"""Deprecated alias of :mod:`pmaccuracy.io.csvio` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .io import csvio as _module

warnings.warn("pmaccuracy.csvio moved to pmaccuracy.io.csvio; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
