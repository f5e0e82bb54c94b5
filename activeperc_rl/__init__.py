"""activeperc_rl: TorchRL training of the mover and the looker (meta-evaluation and baselines).

Entry points: :func:`make_env` (the batched TorchRL env), :class:`TrainConfig`,
:class:`MetaEvaluationLoss`, ``activeperc_rl.train.train`` and ``activeperc_rl.evaluate.evaluate``
(and the console scripts ``activeperc-train`` and ``activeperc-eval``).
"""

try:
    import tensordict  # noqa: F401
    import torch  # noqa: F401
    import torchrl  # noqa: F401
    import yaml  # noqa: F401
except ImportError as error:  # the environment alone was installed
    raise ImportError(
        f"activeperc_rl needs the training extra, and {error.name!r} is not installed: "
        "pip install torch==2.13.0 -e '.[train]' (from a checkout) or pip install 'activeperc[train]'"
    ) from error

from activeperc_rl.config import TrainConfig
from activeperc_rl.envs import ActivePerceptionEnv, make_env
from activeperc_rl.losses import MetaEvaluationLoss

__all__ = ["ActivePerceptionEnv", "MetaEvaluationLoss", "TrainConfig", "make_env"]
