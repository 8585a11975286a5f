"""The documentation's API pages list every public name of the front door (``docs/api.rst``)."""

from __future__ import annotations

import re
from pathlib import Path

import pmaccuracy as pm

API = Path(__file__).resolve().parents[1] / "docs" / "api.rst"


def test_api_pages_list_every_public_name_once():
    listed = re.findall(r"^   (\w+)$", API.read_text(encoding="utf-8"), flags=re.M)
    assert len(listed) == len(set(listed))
    assert set(listed) == set(pm.__all__) - {"__version__"}
