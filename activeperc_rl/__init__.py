"""activeperc_rl: TorchRL training of the mover and the looker (meta-evaluation and baselines).

Entry points: :func:`make_env` (the batched TorchRL env), :class:`TrainConfig`,
:class:`MetaEvaluationLoss`, ``activeperc_rl.train.train`` and ``activeperc_rl.evaluate.evaluate``
(and the console scripts ``activeperc-train`` and ``activeperc-eval``).
"""

from activeperc_rl.config import TrainConfig
from activeperc_rl.envs import ActivePerceptionEnv, make_env
from activeperc_rl.losses import MetaEvaluationLoss

__all__ = ["ActivePerceptionEnv", "MetaEvaluationLoss", "TrainConfig", "make_env"]
