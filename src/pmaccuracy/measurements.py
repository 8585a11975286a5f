"""Deprecated alias of :mod:`pmaccuracy.experiment.measurements` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .experiment import measurements as _module

warnings.warn("pmaccuracy.measurements moved to pmaccuracy.experiment.measurements; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
