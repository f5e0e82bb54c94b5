"""The environment installs and runs without the training extra."""

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
gymnasium.make("activeperc/Joint-v0").reset(seed=0)
gymnasium.make_vec("activeperc/FixedForward-v0", num_envs=2).reset(seed=0)
print(" ".join(sorted(m for m in sys.modules if m.split(".")[0] in {names})))
"""


def test_the_env_imports_nothing_of_the_training_extra():
    """pyproject.toml's base dependencies hold only what ``activeperc_env`` imports; this keeps it that way."""
    script = SCRIPT.replace("{names}", repr(set(TRAIN_ONLY)))
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == ""
