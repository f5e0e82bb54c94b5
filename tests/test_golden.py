"""Every room version gives the episodes it always gave: golden traces through the core, PettingZoo and TorchRL.

The committed digests (``tests/golden/traces.json``, written by ``python tests/golden.py``) cover the views, the
physics state, the range readings, rewards and ends of seeded rooms under fixed actions. v0's were written by the
code before v1 existed, so they prove the Figure 1 pilot's room unchanged. A failure names the first cycle that
differs: a MuJoCo, Mesa or numpy upgrade, or a change of ours, made the same seed give another episode.
"""

import json

import pytest
from golden import TRACES, core_trace, parallel_env_trace, torchrl_trace

from activeperc_env.names import VERSIONS

STORED = json.loads(TRACES.read_text())


def first_difference(ours: list[str], stored: list[str]) -> str:
    for cycle, (mine, theirs) in enumerate(zip(ours, stored, strict=False)):
        if mine != theirs:
            return f"cycle {cycle}"
    return f"lengths {len(ours)} and {len(stored)}"


@pytest.mark.parametrize("version", VERSIONS)
def test_core_gives_the_stored_episodes(version):
    ours, stored = core_trace(version), STORED[f"v{version}"]["core"]
    for fov, rows in stored.items():
        assert ours[fov] == rows, f"v{version} {fov}: first difference at {first_difference(ours[fov], rows)}"


@pytest.mark.parametrize("version", VERSIONS)
def test_pettingzoo_gives_the_stored_episodes(version):
    ours, stored = parallel_env_trace(version), STORED[f"v{version}"]["parallel_env"]
    assert ours == stored, f"v{version}: first difference at {first_difference(ours, stored)}"


@pytest.mark.parametrize("version", VERSIONS)
def test_torchrl_env_gives_the_stored_episodes(version):
    ours, stored = torchrl_trace(version), STORED[f"v{version}"]["torchrl"]
    assert ours == stored, f"v{version}: first difference at {first_difference(ours, stored)}"
