"""Deprecated alias of :mod:`pmaccuracy.experiment.iso9283` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .experiment import iso9283 as _module

warnings.warn("pmaccuracy.iso9283 moved to pmaccuracy.experiment.iso9283; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
