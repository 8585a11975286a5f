"""Deprecated alias of :mod:`pmaccuracy.model._tomlio` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import _tomlio as _module

warnings.warn("pmaccuracy._tomlio moved to pmaccuracy.model._tomlio; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
