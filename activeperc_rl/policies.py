"""Policy files: a run's deployed networks alone (a few MB), and the pretrained ones shipped in the package.

Watch or score a trained mover and looker before training one::

    from activeperc_rl import pretrained
    from activeperc_rl.evaluate import evaluate

    config, mover_policy, looker = pretrained("fov60")
    print(evaluate(config, mover_policy, looker, episodes=100))

``activeperc-eval --pretrained fov60 --video episode.gif`` does the same from the shell; :func:`save_policy` turns a
run of your own into such a file, which ``activeperc-eval POLICY.pt`` and :func:`load_policy_file` read.
"""

from __future__ import annotations

from pathlib import Path

import torch

from activeperc_rl.envs import torch_device
from activeperc_rl.recipe import TrainConfig, make_method
from activeperc_rl.runtime.atomic import atomic_path
from activeperc_rl.runtime.checkpoint import CHECKPOINT, EVAL, load_checkpoint, read_saved, restored_method

FORMAT = "activeperc-policy"
"""The ``format`` entry of a policy file."""
WEIGHTS = Path(__file__).parent / "weights"
"""The folder of the shipped policy files."""
PRETRAINED = {
    "fov60": "activeperc-train --out runs/pretrained/fov60",
    "fov100": "activeperc-train --fov 100 --out runs/pretrained/fov100",
}
"""The shipped policies (``activeperc_rl/weights/NAME.pt``) and the command that trained each (seed 0, the
default recipe in the default room, room v3)."""


def pretrained(name: str = "fov60", device="cpu"):
    """A shipped policy, ``(config, mover_policy, looker)`` as :func:`~activeperc_rl.evaluate.load_policy` returns:
    ``"fov60"`` or ``"fov100"``, the default recipe trained at that field of view (:data:`PRETRAINED`)."""
    if name not in PRETRAINED:
        raise ValueError(f"pretrained policy {name!r} is unknown: expected one of {tuple(PRETRAINED)}")
    return load_policy_file(WEIGHTS / f"{name}.pt", device)


def save_policy(run: str | Path, path: str | Path, trained_by: str = "") -> dict:
    """Write the deployed networks of ``run`` (a run directory or a checkpoint file) to ``path``, in half precision,
    with the run's config, frames, final evaluation (``eval.json`` beside the checkpoint, when there) and
    ``trained_by`` (the command that trained it). Returns what it wrote, less the weights."""
    run = Path(run)
    file = run / CHECKPOINT if run.is_dir() else run
    state = load_checkpoint(file)
    config, method = restored_method(state, file, torch.device("cpu"))
    names = _policy_modules(method)
    evaluation = file.parent / EVAL
    about = {
        "format": FORMAT,
        "config": config.to_dict(),
        "frames": int(state["frames"]),
        "trained_by": trained_by,
        "eval": evaluation.read_text() if evaluation.is_file() else "",
    }
    modules = {name: _cast(method.modules[name].state_dict(), torch.float16) for name in names}
    with atomic_path(path) as temporary:
        torch.save(about | {"modules": modules}, temporary)
    return about | {"modules": names}


def load_policy_file(path: str | Path, device="cpu"):
    """Read a file of :func:`save_policy`: ``(config, mover_policy, looker)``. ``ValueError`` naming the file when it
    is missing, damaged (a part that does not match its CRC-32 checksum) or not a policy file."""
    return policy_from_saved(read_policy_file(path), path, device)


def read_policy_file(path: str | Path) -> dict:
    """The contents of a policy file, checked: ``format``, ``config``, ``frames``, ``trained_by``, ``eval`` (the
    run's ``eval.json`` as text) and ``modules`` (each network's half-precision weights)."""
    saved = read_saved(path, "policy file", weights_only=True)
    if not is_policy(saved):
        raise ValueError(f"{str(path)!r} is not an activeperc policy file")
    return saved


def policy_from_saved(saved: dict, path: str | Path, device="cpu"):
    """``(config, mover_policy, looker)`` built from the contents of the policy file ``path``; ``ValueError`` naming
    the file when they do not make one."""
    try:
        config = TrainConfig.from_saved(saved["config"])
    except ValueError as error:
        raise ValueError(f"policy file {str(path)!r} is unusable: {error}") from error
    method = make_method(config, torch_device(device), start=False)
    missing = set(_policy_modules(method)) - set(saved["modules"])
    if missing:
        raise ValueError(f"policy file {str(path)!r} is unusable: it lacks the networks {sorted(missing)}")
    for name, state_dict in saved["modules"].items():
        if name not in method.modules:
            raise ValueError(f"policy file {str(path)!r} is unusable: {config.method} has no network {name!r}")
        try:
            method.modules[name].load_state_dict(_cast(state_dict, torch.float32))
        except (AttributeError, RuntimeError, ValueError) as error:
            raise ValueError(f"policy file {str(path)!r} is unusable: its {name!r} does not fit its config") from error
    return (config, *method.policy())


def is_policy(saved) -> bool:
    """Whether ``saved`` (what ``torch.load`` read) is the contents of a policy file."""
    return (
        isinstance(saved, dict)
        and saved.get("format") == FORMAT
        and isinstance(saved.get("config"), dict)
        and isinstance(saved.get("modules"), dict)
        and all(isinstance(module, dict) for module in saved["modules"].values())
    )


def _cast(state_dict: dict, dtype: torch.dtype) -> dict:
    """``state_dict`` with its floating-point tensors in ``dtype`` (the others as they are)."""
    return {key: value.to(dtype) if value.is_floating_point() else value for key, value in state_dict.items()}


def _policy_modules(method) -> list[str]:
    """The names of ``method``'s networks that its deployed policy runs: those whose every weight is one of the
    policy's (the critic shares the actor's encoder, not its head). They hold every weight of the policy."""
    policy = [module for module in method.policy() if module is not None]
    weights = {id(p) for module in policy for p in module.parameters()}
    names = [
        name
        for name, module in method.modules.items()
        if all(id(p) in weights for p in module.parameters()) and any(True for _ in module.parameters())
    ]
    held = {id(p) for name in names for p in method.modules[name].parameters()}
    if held != weights:
        raise ValueError(f"{type(method).__name__}'s policy shares weights with networks it does not run alone")
    return names
