"""Rooms are records: one module each, one registry line, read by everything else; nothing else compares versions."""

import ast
import importlib
import re
from pathlib import Path

import mujoco
import pytest

import activeperc_env
from activeperc_env import EnvConfig, Simulator, rooms
from activeperc_env.rooms import DEFAULT, ROOMS, Room

PACKAGE = Path(activeperc_env.__file__).parent
DOCS = Path(__file__).resolve().parent.parent / "docs"


def test_every_room_module_is_registered_under_its_version():
    modules = sorted(path.stem for path in (PACKAGE / "rooms").glob("v*.py"))
    assert modules == [f"v{version}" for version in sorted(ROOMS)]
    for version, record in ROOMS.items():
        assert importlib.import_module(f"activeperc_env.rooms.v{version}").ROOM is record
        assert isinstance(record, Room) and record.version == version and record.name == f"activeperc_v{version}"
    assert DEFAULT in ROOMS and EnvConfig().version == DEFAULT


@pytest.mark.parametrize("version", ROOMS)
def test_a_room_builds_what_its_record_says(version):
    record = ROOMS[version]
    config = EnvConfig(version=version)
    assert config.room is record
    assert {name: getattr(config, name) for name in record.defaults} == record.defaults
    sim = Simulator(config)
    assert isinstance(sim._base, record.base) and sim.model.opt.timestep == record.physics_timestep
    assert mujoco.MjModel.from_xml_path(str(record.scene)).opt.timestep == record.physics_timestep
    assert activeperc_env.mover_actions(version) == record.mover_actions
    sim.reset(seeds=[0])
    with pytest.raises(ValueError, match=re.escape(str(record.mover_actions))):
        sim.move([3])
    heading = sim.pose()[1]
    sim.move([0])
    assert (abs(sim.pose()[1] - heading) > 0.01) == record.turns


def test_the_room_defaults_of_a_new_room_come_from_its_record_alone():
    """A room's options left None take its record's defaults: no table of defaults lives anywhere else."""
    assert set(rooms.ROOMS[DEFAULT].defaults) == set(activeperc_env.config.ROOM_DEFAULTS)
    for version, record in ROOMS.items():
        for name, value in record.defaults.items():
            assert getattr(EnvConfig(version=version), name) == value


def test_no_module_outside_rooms_compares_version_numbers():
    """``version`` may be passed on, saved and looked up in the registry (``version in ROOMS``), but what a room is
    comes from its record: no other comparison of it."""
    offenders = []
    for path in [*PACKAGE.glob("*.py"), *(PACKAGE.parent / "activeperc_rl").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare):
                names = {n.attr if isinstance(n, ast.Attribute) else getattr(n, "id", None) for n in ast.walk(node)}
                lookup = (
                    isinstance(node.ops[0], (ast.In, ast.NotIn)) and getattr(node.comparators[0], "id", "") == "ROOMS"
                )
                if "version" in names and not lookup:
                    offenders.append(f"{path.name}:{node.lineno}")
    assert offenders == [], offenders
    assert not re.search(r"version\s*(==|!=|<|>|in\b)", (PACKAGE / "core.py").read_text())


def test_the_env_docstrings_and_env_md_give_the_records_version_history():
    entries = rooms.version_history().splitlines()
    assert len(entries) == len(ROOMS) and entries[0].startswith(f"v{max(ROOMS)}")
    for cls in (activeperc_env.raw_env, activeperc_env.JointEnv, activeperc_env.FixedForwardEnv):
        history = " ".join(cls.__doc__.split("Version History:")[1].split())
        for version, record in ROOMS.items():
            assert " ".join(record.summary.split()) in history, (cls, version)
    env_md = (DOCS / "env.md").read_text()
    assert rooms.version_history(markdown=True) in env_md  # python docs/tables.py writes it there
