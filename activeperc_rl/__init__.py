"""activeperc_rl: TorchRL training of the mover and the looker (meta-evaluation and baselines).

Entry points: :func:`make_env` (the batched TorchRL env, an :class:`ActivePerceptionEnv`), :class:`TrainConfig` (a
training recipe: ``TrainConfig()`` is the one that works in the default room), :func:`pretrained` (a trained mover
and looker shipped with the package), :class:`MetaEvaluationLoss`,
``activeperc_rl.train.train`` and ``activeperc_rl.evaluate.evaluate`` (and the console scripts ``activeperc-train``
and ``activeperc-eval``).
"""

import importlib
import importlib.util

_missing = [name for name in ("torch", "tensordict", "torchrl", "yaml") if importlib.util.find_spec(name) is None]
if _missing:  # the environment alone was installed
    raise ImportError(
        f"activeperc_rl (training, activeperc-train, activeperc-eval) needs the 'train' extra, and {_missing} are "
        "not installed: run pip install torch==2.13.0 'activeperc[train]' (in a checkout of activeperc: "
        "pip install torch==2.13.0 -e '.[train]'; torch pinned: an unpinned torch pulls a CUDA build of several GB)"
    )

# the public names load torch when first used, so that a command can set itself up before (activeperc_rl.commands)
_PUBLIC = {
    "ActivePerceptionEnv": "activeperc_rl.envs",
    "MetaEvaluationLoss": "activeperc_rl.losses",
    "TrainConfig": "activeperc_rl.recipe",
    "make_env": "activeperc_rl.envs",
    "pretrained": "activeperc_rl.policies",
}
__all__ = list(_PUBLIC)


def __getattr__(name: str):
    """A public name, imported from its module on first use."""
    if name not in _PUBLIC:
        raise AttributeError(f"module 'activeperc_rl' has no attribute {name!r}")
    return getattr(importlib.import_module(_PUBLIC[name]), name)


def __dir__() -> list[str]:
    """The module's names with the public ones not yet imported (for tab completion)."""
    return sorted(set(globals()) | set(_PUBLIC))
