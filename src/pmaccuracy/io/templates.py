"""Template robot and clearance files, one pair per architecture, shipped with the package.

Each template is a commented TOML file (every key explained with its unit) describing a robot that
reaches its home pose, ready to be copied and edited: ``pmaccuracy template 3-RRR > my_3rrr.toml``.

>>> from pmaccuracy.io.templates import ARCHITECTURES, template_text
>>> ARCHITECTURES
('3-PPR', '3-RPR', '3-RRR', '3-PRR', 'serial')
>>> SPATIAL_ARCHITECTURES
('6-UPS', 'delta', '3-RPS', '3-PRS', '3-UPU')
>>> template_text("3-rrr").splitlines()[0]
'# A 3-RRR robot file: copy it, change the numbers, then'
"""

from __future__ import annotations

from importlib import resources

from ..errors import ConfigError

#: The planar architectures that have templates (robot and clearances), as the command line names them.
ARCHITECTURES = ("3-PPR", "3-RPR", "3-RRR", "3-PRR", "serial")
#: The spatial architectures that have templates (robot and per-joint error sources).
SPATIAL_ARCHITECTURES = ("6-UPS", "delta", "3-RPS", "3-PRS", "3-UPU")


def architecture_name(arch: str, key: str = "ARCH") -> str:
    """The canonical spelling of ``arch`` (case does not matter), or a ConfigError listing the valid ones."""
    every = ARCHITECTURES + SPATIAL_ARCHITECTURES
    names = {a.lower(): a for a in every}
    found = names.get(str(arch).strip().lower())
    if found is None:
        raise ConfigError(f"no template for {arch!r}: choose one of {', '.join(every)}", key=key)
    return found


def template_resource(arch: str, clearances: bool = False):
    """The shipped file (an :mod:`importlib.resources` traversable) of ``arch``'s robot or clearance template."""
    folder = architecture_name(arch).lower()
    name = "clearances.toml" if clearances else "robot.toml"
    return resources.files("pmaccuracy") / "data" / "templates" / folder / name


def template_text(arch: str, clearances: bool = False) -> str:
    """The text of ``arch``'s robot template (``clearances=True``: its per-joint clearance template)."""
    return template_resource(arch, clearances).read_text(encoding="utf-8")
