"""activeperc_env: the active-perception room of the meta-evaluation paper, for MARL and RL code.

PettingZoo: :func:`env` (AEC, order-enforced), :class:`raw_env`, :class:`parallel_env`; :func:`image_only` wraps
either so that each agent observes its camera image alone (a ``Box``).
Gymnasium (registered on import): ``activeperc/Joint-vK`` and ``activeperc/FixedForward-vK`` for each room ``K``
(``activeperc/Joint``: the newest, room v3, the default); ``gymnasium.make_vec`` steps all their rooms in one batched
core (:class:`JointVectorEnv`, :class:`FixedForwardVectorEnv`). Scripted movers and lookers:
:mod:`activeperc_env.scripted`. Batched core for training: :class:`Simulator`. Options of every env:
:class:`EnvConfig` (``version`` picks the room: :mod:`activeperc_env.rooms`). Agent names :data:`MOVER` and
:data:`LOOKER`; action meanings :func:`mover_actions` (by room) and :data:`LOOKER_ACTIONS`.
Single-agent classes behind the Gymnasium ids: :class:`JointEnv`, :class:`FixedForwardEnv`.
"""

from activeperc_env.gl import choose_backend

choose_backend()

import gymnasium  # noqa: E402

from activeperc_env.config import EnvConfig  # noqa: E402
from activeperc_env.core import LOOKER_ACTIONS, Simulator  # noqa: E402
from activeperc_env.gym_envs import FixedForwardEnv, JointEnv  # noqa: E402
from activeperc_env.gym_vector import FixedForwardVectorEnv, JointVectorEnv  # noqa: E402
from activeperc_env.pettingzoo_env import LOOKER, MOVER, env, parallel_env, raw_env  # noqa: E402
from activeperc_env.rooms import ROOMS, mover_actions  # noqa: E402
from activeperc_env.wrappers import image_only  # noqa: E402

__all__ = [
    "EnvConfig",
    "FixedForwardEnv",
    "FixedForwardVectorEnv",
    "JointEnv",
    "JointVectorEnv",
    "LOOKER",
    "LOOKER_ACTIONS",
    "MOVER",
    "Simulator",
    "env",
    "image_only",
    "mover_actions",
    "parallel_env",
    "raw_env",
]

for _name in ("Joint", "FixedForward"):
    for _version in ROOMS:
        if f"activeperc/{_name}-v{_version}" not in gymnasium.registry:
            gymnasium.register(
                f"activeperc/{_name}-v{_version}",
                entry_point=f"activeperc_env.gym_envs:{_name}Env",
                vector_entry_point=f"activeperc_env.gym_vector:{_name}VectorEnv",
                kwargs={"version": _version},
            )
