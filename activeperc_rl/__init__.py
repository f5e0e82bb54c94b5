"""activeperc_rl: TorchRL training of the mover and the looker (meta-evaluation and baselines).

Entry points: :func:`make_env` (the batched TorchRL env, an :class:`ActivePerceptionEnv`), :class:`TrainConfig` (a
training recipe: ``TrainConfig()`` is the one that works in the default room), :class:`MetaEvaluationLoss`,
``activeperc_rl.train.train`` and ``activeperc_rl.evaluate.evaluate`` (and the console scripts ``activeperc-train``
and ``activeperc-eval``).
"""

import importlib.util

_missing = [name for name in ("torch", "tensordict", "torchrl", "yaml") if importlib.util.find_spec(name) is None]
if _missing:  # the environment alone was installed
    raise ImportError(
        f"activeperc_rl (training, activeperc-train, activeperc-eval) needs the 'train' extra, and {_missing} are "
        "not installed: run pip install torch==2.13.0 'activeperc[train]' (in a checkout of activeperc: "
        "pip install torch==2.13.0 -e '.[train]'; torch pinned: an unpinned torch pulls a CUDA build of several GB)"
    )

from activeperc_rl.envs import ActivePerceptionEnv, make_env  # noqa: E402 (after the check above)
from activeperc_rl.losses import MetaEvaluationLoss  # noqa: E402
from activeperc_rl.recipe import TrainConfig  # noqa: E402

__all__ = ["ActivePerceptionEnv", "MetaEvaluationLoss", "TrainConfig", "make_env"]
