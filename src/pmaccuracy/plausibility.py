"""Deprecated alias of :mod:`pmaccuracy.model.plausibility` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .model import plausibility as _module

warnings.warn("pmaccuracy.plausibility moved to pmaccuracy.model.plausibility; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
