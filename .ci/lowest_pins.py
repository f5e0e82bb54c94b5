"""Print the project's base dependencies (pyproject.toml) each pinned to its lower bound, for pip: what CI installs to
test the environment alone at the oldest versions it claims to work with."""

import re
import sys
import tomllib
from pathlib import Path

project = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())["project"]
pins = []
for requirement in project["dependencies"]:
    lowest = re.match(r"^([A-Za-z0-9_.-]+)\s*>=\s*([0-9][0-9A-Za-z.]*)", requirement)
    if lowest is None:
        sys.exit(f"lowest_pins.py: {requirement!r} has no lower bound '>=': give it one")
    pins.append(f"{lowest[1]}=={lowest[2]}")
print(" ".join(pins))
