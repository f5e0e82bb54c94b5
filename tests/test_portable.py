"""Portable mode's guards: it must start before torch does, and it says so where it cannot (the runs it gives are
checked against committed digests in test_golden.py)."""

import pytest
import torch

from activeperc_rl import cli
from activeperc_rl.recipe import TrainConfig
from activeperc_rl.runtime import portable
from activeperc_rl.train import train


@pytest.fixture
def unpinned(monkeypatch):
    """This process as one started without the pinning variables."""
    for name in portable.PINNED_ENVIRONMENT:
        monkeypatch.delenv(name, raising=False)


def test_portable_must_be_a_bool():
    with pytest.raises(ValueError, match="portable"):
        TrainConfig.from_options(portable="yes")


def test_train_refuses_portable_in_an_unpinned_process(unpinned, tmp_path):
    """train() cannot pin torch's kernels once torch runs: it names the variables, and writes nothing."""
    pins = "ATEN_CPU_CAPABILITY=avx2 ONEDNN_MAX_CPU_ISA=AVX2 MKL_CBWR=COMPATIBLE GALLIUM_DRIVER=softpipe "
    pins += "DRAW_USE_LLVM=0"
    with pytest.raises(ValueError, match=pins):
        train(TrainConfig.from_options(portable=True, frames=256), tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_the_cli_called_in_process_names_the_problem(unpinned, tmp_path, capsys):
    """main(argv) inside another program does not replace that program's process: it refuses with status 2."""
    assert cli.main(["--portable", "--frames", "256", "--out", str(tmp_path / "run"), "--no-progress"]) == 2
    assert "portable=True needs torch's CPU kernels pinned" in capsys.readouterr().err


def test_no_second_restart_when_the_variables_did_not_pin(monkeypatch):
    """A process started with the variables that still runs other kernels is an error, not a restart loop."""
    for name, value in portable.PINNED_ENVIRONMENT.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setattr(portable, "cpu_capability", lambda: "AVX512")  # as if torch had started before them
    with pytest.raises(ValueError, match="are set and torch still uses"):
        portable.restart_pinned("activeperc-train")


def test_a_pinned_process_is_not_restarted(monkeypatch):
    for name, value in portable.PINNED_ENVIRONMENT.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setattr(portable, "cpu_capability", lambda: portable.PINNED_CAPABILITY)
    monkeypatch.setattr(portable.os, "execve", lambda *args: pytest.fail("restarted a pinned process"))
    portable.restart_pinned("activeperc-train")


def test_a_cpu_without_avx2_is_refused(unpinned, monkeypatch):
    monkeypatch.setattr(portable, "cpu_capability", lambda: "DEFAULT")
    with pytest.raises(ValueError, match="this CPU's are DEFAULT: run without --portable"):
        portable.restart_pinned("activeperc-train")


def test_the_digest_of_a_state_sees_every_bit():
    def state():
        return {"modules": {"actor": {"weight": torch.ones(3, 2)}}, "optimizers": {"step": 4}}

    flipped = state()
    flipped["modules"]["actor"]["weight"][1, 1] = torch.nextafter(torch.tensor(1.0), torch.tensor(2.0))
    assert portable.state_digest(state()) == portable.state_digest(state())
    assert portable.state_digest(state()) != portable.state_digest(flipped)
    assert portable.state_digest(state()) != portable.state_digest(state() | {"optimizers": {"step": 5}})


@pytest.mark.parametrize("method", ["meta", "fixed_forward"])
def test_portable_mode_takes_the_fused_adam_step(method):
    """The unfused Adam step's square root is MKL's, which rounds by CPU vendor; portable mode's step is torch's
    fused one, and the default keeps the unfused step (so default runs keep their bits)."""
    from activeperc_rl.recipe import make_method

    small = dict(method=method, channels=(4,), hidden_size=8)
    for is_portable in (False, True):
        trainer = make_method(TrainConfig.from_options(portable=is_portable, **small), torch.device("cpu"), start=False)
        adams = [o for o in trainer.optimizers.values() if isinstance(o, torch.optim.Adam)]
        assert adams and all(bool(g["fused"]) is is_portable for o in adams for g in o.param_groups)


def test_a_resumed_portable_run_takes_the_fused_step_whatever_its_checkpoint_took():
    """Adam's load_state_dict takes the saved groups' settings: a portable run resumed from a checkpoint of the
    unfused step (portable mode before it took the fused one) still takes the fused step."""
    from activeperc_rl.recipe import make_method
    from activeperc_rl.runtime.checkpoint import restore_method

    small = dict(method="fixed_forward", channels=(4,), hidden_size=8)
    unfused = make_method(TrainConfig.from_options(**small), torch.device("cpu"), start=False)
    resumed = make_method(TrainConfig.from_options(portable=True, **small), torch.device("cpu"), start=False)
    restore_method(resumed, {"method": unfused.state_dict()}, "checkpoint.pt")
    adams = [o for o in resumed.optimizers.values() if isinstance(o, torch.optim.Adam)]
    assert adams and all(g["fused"] is True for o in adams for g in o.param_groups)
