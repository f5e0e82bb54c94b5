"""The environment installs and runs without the training extra; the wheel holds what a user needs."""

import subprocess
import sys

TRAIN_ONLY = ("torch", "torchrl", "tensordict", "yaml", "tqdm", "tensorboard", "matplotlib")

SCRIPT = """
import sys
import gymnasium
import activeperc_env

env = activeperc_env.env(render_mode="rgb_array")
env.reset(seed=0)
for agent in env.agent_iter(max_iter=8):
    env.step(env.action_space(agent).sample())
env.render()
gymnasium.make("activeperc/Joint-v1").reset(seed=0)
gymnasium.make_vec("activeperc/FixedForward-v1", num_envs=2).reset(seed=0)
print(" ".join(sorted(m for m in sys.modules if m.split(".")[0] in {names})))
"""


def test_the_env_imports_nothing_of_the_training_extra():
    """pyproject.toml's base dependencies hold only what ``activeperc_env`` imports; this keeps it that way."""
    script = SCRIPT.replace("{names}", repr(set(TRAIN_ONLY)))
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == ""


def test_the_wheel_holds_every_module_the_scene_and_the_type_marker(tmp_path):
    """A user's ``pip install`` from a wheel (not our editable install) gets the scene XML, every module, the named
    presets and the ``py.typed`` marker (type checkers read our annotations only with it), and the three console
    scripts."""
    import shutil
    import zipfile
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    source = tmp_path / "source"  # a copy, so that the build leaves nothing in the repository
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(root / name, source / name)
    for package in ("activeperc_env", "activeperc_rl"):
        shutil.copytree(root / package, source / package, ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", source, "--no-deps", "-q", "-w", tmp_path],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (wheel,) = tmp_path.glob("activeperc-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {
        str(path.relative_to(root))
        for package in ("activeperc_env", "activeperc_rl")
        for path in (root / package).rglob("*")
        if path.is_file() and "__pycache__" not in path.parts
    }
    shipped = {"activeperc_env/assets/scene.xml", "activeperc_env/py.typed", "activeperc_rl/py.typed"}
    assert shipped | {"activeperc_rl/presets/paper.yaml", "activeperc_rl/presets/pilot.yaml"} <= expected
    assert expected <= names, f"missing from the wheel: {sorted(expected - names)}"
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    scripts = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert all(f"{s} =" in scripts for s in ("activeperc-train", "activeperc-eval", "activeperc-episode"))


def test_training_without_its_extra_names_what_is_missing_and_the_pinned_install():
    """With the environment alone installed, ``activeperc_rl`` (and so ``activeperc-train``) names every missing
    package of the ``train`` extra and the install command with torch pinned."""
    script = (
        "import importlib.util\n"
        "find = importlib.util.find_spec\n"
        "importlib.util.find_spec = lambda name, *a: None if name in ('torch', 'torchrl') else find(name, *a)\n"
        "import activeperc_rl\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 1
    message = out.stderr.strip().splitlines()[-1]
    assert "needs the 'train' extra, and ['torch', 'torchrl'] are not installed" in message, message
    assert "pip install torch==2.13.0 'activeperc[train]'" in message, message  # from a wheel or an index
    assert "pip install torch==2.13.0 -e '.[train]'" in message, message  # in a checkout


def test_the_oldest_python_we_allow_is_one_our_dependencies_allow():
    """pyproject.toml's requires-python starts no lower than any installed dependency's own: pip would otherwise
    offer the project to a Python on which a dependency has no release (mujoco 4.0.0 needs 3.11)."""
    import importlib.metadata
    import tomllib
    from pathlib import Path

    from packaging.requirements import Requirement
    from packaging.specifiers import SpecifierSet

    project = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())["project"]
    ours = SpecifierSet(project["requires-python"])
    oldest = next(f"3.{minor}" for minor in range(0, 100) if f"3.{minor}" in ours)
    requirements = project["dependencies"] + project["optional-dependencies"]["train"]
    refusing = []
    for name in sorted({Requirement(r).name for r in requirements}):
        try:
            theirs = SpecifierSet(importlib.metadata.metadata(name)["Requires-Python"] or "")
        except importlib.metadata.PackageNotFoundError:  # the training extra is not installed here
            continue
        if oldest not in theirs:
            refusing.append(f"{name} ({theirs})")
    assert not refusing, f"requires-python {ours} admits Python {oldest}, which these refuse: {refusing}"
