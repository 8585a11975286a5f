"""Deprecated alias of :mod:`pmaccuracy.model.sources` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import sources as _module

warnings.warn("pmaccuracy.sources moved to pmaccuracy.model.sources; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
