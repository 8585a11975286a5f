"""Deprecated alias of :mod:`pmaccuracy.kinematics.workspace` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .kinematics import workspace as _module

warnings.warn("pmaccuracy.workspace moved to pmaccuracy.kinematics.workspace; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
