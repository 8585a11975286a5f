"""Deprecated alias of :mod:`pmaccuracy.experiment.virtual_rig` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .experiment import virtual_rig as _module

warnings.warn("pmaccuracy.virtual_rig moved to pmaccuracy.experiment.virtual_rig; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
