"""The benchmark scripts at their tiniest sizes: env_scaling's CSV, plot and memory samples, the breakdowns, MiniWorld's
child process, the rounds' ratios and the harness's part timers."""

import csv
import importlib
import importlib.util
import json
import re
import sys
import time
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture(scope="module", autouse=True)
def benchmarks_on_the_path():
    """benchmarks/ on ``sys.path``, as it is for a script run from it (benchmarks/ is not a package); its modules
    forgotten after this file's tests."""
    sys.path.insert(0, str(BENCHMARKS))
    yield
    sys.path.remove(str(BENCHMARKS))
    for name, module in list(sys.modules.items()):
        if Path(getattr(module, "__file__", None) or "/").parent == BENCHMARKS:
            del sys.modules[name]


def load_script(name):
    """A benchmark script or shared module of benchmarks/ as a module."""
    return importlib.import_module(name)


@pytest.fixture
def env_scaling():
    return load_script("env_scaling")


@pytest.fixture
def peer():
    return load_script("peer")


@pytest.fixture
def harness():
    return load_script("harness")


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_env_scaling_writes_csv_plot_and_memory(env_scaling, tmp_path):
    rates, plot, memory = tmp_path / "out" / "scaling.csv", tmp_path / "scaling.png", tmp_path / "memory.csv"
    argv = ["--num-envs", "1", "2", "--seconds", "0.2", "--warmup", "0.05", "--no-peer", "--rounds", "2"]
    argv += ["--memory-episodes", "5", "--memory-rooms", "5", "--csv", str(rates), "--plot", str(plot)]
    report = env_scaling.main([*argv, "--memory-csv", str(memory)])

    rows = read_csv(rates)
    assert list(rows[0]) == ["num_envs", "cycles_per_s", "miniworld_steps_per_s", "ratio"]
    assert [row["num_envs"] for row in rows] == ["1", "2"]
    assert all(float(row["cycles_per_s"]) > 0 for row in rows)
    assert len(report["rounds"]) == 2  # the CSV holds each N's median over the rounds
    assert [float(row["cycles_per_s"]) for row in rows] == pytest.approx(
        [(report["rounds"][0][n] + report["rounds"][1][n]) / 2 for n in (1, 2)]
    )
    assert all(row["miniworld_steps_per_s"] == row["ratio"] == "" for row in rows)  # --no-peer
    assert plot.stat().st_size > 0
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["memory.csv", "out", "scaling.csv", "scaling.png"]

    samples = read_csv(memory)
    assert list(samples[0]) == ["episodes", "rss_mib"]
    assert samples[0]["episodes"] == "0" and int(samples[-1]["episodes"]) >= 5
    assert report["memory"]["episodes"] >= 5 and report["memory"]["start_mib"] > 0
    assert report["goal_met"] is None  # neither MiniWorld nor N=64 was measured


def test_env_scaling_times_the_bare_simulator_in_each_round(env_scaling, tmp_path, monkeypatch, capsys):
    """Also: without --csv and --plot it writes nothing (the committed results are never overwritten by default)."""
    monkeypatch.setattr(env_scaling, "GOAL_NUM_ENVS", 2)  # the split's N, small enough for a test
    monkeypatch.chdir(tmp_path)
    argv = ["--num-envs", "1", "2", "--seconds", "0.2", "--warmup", "0.05", "--no-peer", "--rounds", "2"]
    report = env_scaling.main(argv)
    assert list(tmp_path.iterdir()) == [] and "wrote" not in capsys.readouterr().out

    split = report["core_split_s_per_cycle"]
    assert all(split[part] > 0 for part in ("move", "render", "look", "cycles_per_s"))
    extra = split["torchrl_overhead_rounds"]
    assert len(extra) == 2  # one difference per round, each against that round's TorchRL figure
    assert split["torchrl_overhead"] == pytest.approx(sum(extra) / 2)
    for rates, alone, difference in zip(report["rounds"], report["core_split_rounds"], extra, strict=True):
        assert difference == pytest.approx(2 / rates[2] - 2 / alone["cycles_per_s"])  # whole cycles, not parts


def test_env_scaling_refuses_bad_values(env_scaling, capsys):
    with pytest.raises(SystemExit):
        env_scaling.main(["--num-envs", "4", "0"])
    assert "num_envs must be >= 1, got 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        env_scaling.main(["--rounds", "0"])
    assert "rounds must be >= 1, got 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        env_scaling.main(["--seconds", "nan"])  # it never ended
    assert "seconds must be > 0, got nan" in capsys.readouterr().err


@pytest.mark.parametrize(
    "script, argv, error",
    [
        ("env_speed", ["--rounds", "0"], "rounds must be >= 1, got 0"),
        ("train_speed", ["--seconds", "0"], "seconds must be > 0, got 0"),
        ("train_speed", ["--flip", "lr"], "--flip lr: not a true/false option"),
        ("train_speed", ["--flip", "meta"], "--flip meta: not a true/false option"),
        ("train_speed", ["--variant", "num_envs=x"], "--variant: run.num_envs='x' is invalid"),
        ("train_speed", ["--variant", "num_envs"], "--variant 'num_envs': expected OPTION=VALUE"),
        ("view_profile", ["--views", "0"], "views must be >= 1, got 0"),
        ("portable_speed", ["--frames", "0"], "frames must be >= 1, got 0"),
        ("portable_speed", ["--method", "nothing"], "invalid choice: 'nothing'"),
        ("portable_bits", ["--only", "nothing"], "invalid choice: 'nothing'"),
        ("portable_ops", ["--without", "NOTHING"], "invalid choice: 'NOTHING'"),
        ("warp_profile", ["--repeats", "0"], "repeats must be >= 1, got 0"),
        ("warp_profile", ["--device", "tpu"], "device='tpu' is invalid"),
        ("compile_speed", ["--threads", "0"], "threads must be >= 1, got 0"),
    ],
)
def test_every_script_refuses_bad_values_before_timing(script, argv, error, capsys):
    with pytest.raises(SystemExit):
        load_script(script).main(argv)
    assert error in capsys.readouterr().err


def test_env_scaling_refuses_an_output_it_could_not_write_before_timing(env_scaling, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(env_scaling, "bench_rooms", lambda *args: pytest.fail("timed before checking --csv"))
    with pytest.raises(SystemExit):
        env_scaling.main(["--num-envs", "1", "--no-peer", "--csv", str(tmp_path)])
    assert f"--csv: {str(tmp_path)!r} is a directory" in capsys.readouterr().err


def test_aec_breakdown_times_every_part_and_leaves_the_simulator_class_alone(harness):
    from activeperc_env.core import Simulator

    module = load_script("env_speed")
    originals = [getattr(Simulator, part) for part in harness.SIMULATOR_PARTS]
    result = module.aec_breakdown(seconds=0.5, warmup=0.1, seed=0)
    assert [getattr(Simulator, part) for part in harness.SIMULATOR_PARTS] == originals
    assert all(result[part] > 0 for part in ("move", "render", "look"))
    assert 0 < result["rest"] < result["total"]


def test_env_speed_reports_every_figure_of_the_default_room_without_the_peer(capsys):
    from activeperc_env.rooms import DEFAULT

    report = load_script("env_speed").main(["--seconds", "0.05", "--warmup", "0", "--rounds", "1", "--no-peer"])
    assert set(report["rounds"][0]) == {f"{key}_v{DEFAULT}" for key in load_script("env_speed").FIGURES}
    assert all(rate > 0 for rate in report["rounds"][0].values())
    assert report["miniworld_error"] == "skipped (--no-peer)" and report["goals_met"] == {}
    out = capsys.readouterr().out
    assert (
        f"where a v{DEFAULT} AEC cycle goes" in out and "ratios and goals: unknown, MiniWorld was not measured" in out
    )


def test_env_speed_counts_rooms_and_cycles(monkeypatch):
    """One call of each figure's step, as timed_rate makes them: the core counts its rooms, the AEC env one cycle of
    both agents (each reading its observation first, as a PettingZoo loop does); its GL renderer is named."""
    module = load_script("env_speed")
    monkeypatch.setattr(load_script("harness"), "timed_rate", lambda step, seconds, warmup: step())
    assert module.bench_core(3, seconds=1.0, warmup=0.0, seed=0) == 3
    env, cycle = module.random_aec(seed=0)
    try:
        reads = []
        monkeypatch.setattr(type(env), "last", lambda self, *args: reads.append(self.agent_selection))
        assert cycle() == 1 and reads == ["mover_0", "looker_0"]
        assert module.gl_renderer_name(env.unwrapped.sim) not in ("", "?")
    finally:
        env.close()


def test_each_round_is_divided_by_the_peer_figures_around_it(harness):
    assert harness.bracketed_ratios([300.0, 600.0], [100.0, 200.0, 400.0]) == [2.0, 2.0]
    with pytest.raises(ValueError, match="2 peer figures for 2 rounds: expected 3"):
        harness.bracketed_ratios([1.0, 2.0], [1.0, 2.0])
    assert harness.spread([0.5, 0.9, 0.7], 2, "x") == "0.70x (0.50x, 0.90x, 0.70x)"
    assert harness.spread([0.5], 1) == "0.5"
    assert harness.rounds_met([0.9, 1.0, 1.2], 1.0) == "met in 2 of 3 rounds"
    assert harness.verdict(True, [0.9, 1.0, 1.2], 1.0, 2) == "MET (median; met in 2 of 3 rounds; 2 usable CPUs)"
    assert harness.verdict(False, [0.9], 1.0, 4) == "NOT MET (median; met in 0 of 1 rounds; 4 usable CPUs)"
    assert harness.verdict(None, [], 1.0, 2) == "UNKNOWN"
    assert harness.of_rounds(3) == "median of 3 rounds" and harness.of_rounds(1) == "one round"


class Room:
    def wait(self, seconds):
        time.sleep(seconds)
        return seconds


def test_the_stopwatch_times_methods_only_within_its_block_and_restores_them(harness):
    stopwatch, room, wait = harness.Stopwatch(), Room(), Room.wait
    with stopwatch.watching(Room, ["wait"]):  # a class: every instance's calls
        assert room.wait(0.02) == 0.02
    assert Room.wait is wait
    room.wait(0.2)  # after the block: not timed
    with stopwatch.watching(room, ["wait"]):  # an instance: the class untouched
        assert Room.wait is wait and room.wait(0.01) == 0.01
    assert "wait" not in vars(room)
    assert 0.03 <= stopwatch.spent["wait"] < 0.2
    stopwatch.restart()
    assert stopwatch.spent == {"wait": 0.0}


def test_a_timed_call_inside_another_counts_in_its_own_part_only(harness):
    stopwatch = harness.Stopwatch()
    inner = stopwatch.timed("inner", time.sleep)

    def outer_work():
        time.sleep(0.02)
        inner(0.05)

    stopwatch.timed("outer", outer_work)()
    assert 0.05 <= stopwatch.spent["inner"] < 0.2  # a busy machine oversleeps
    assert 0.02 <= stopwatch.spent["outer"] < 0.05  # its own 20 ms, not the inner call's 50 as well


def test_timed_parts_gives_each_parts_seconds_per_unit_after_the_warm_up(harness):
    stopwatch = harness.Stopwatch()
    nap = stopwatch.timed("nap", time.sleep)

    def step():  # two units of 5 ms of nap each
        nap(0.01)
        return 2

    rate, per_unit = harness.timed_parts(step, seconds=0.2, warmup=0.2, stopwatch=stopwatch)
    assert 0.005 <= per_unit["nap"] < 0.009  # the warm-up's naps would double it; a busy machine oversleeps a little
    assert 0.6 < rate * per_unit["nap"] <= 1  # the share of the timed seconds spent napping


def test_the_peer_line_gives_every_figure_or_why_there_is_none(peer):
    info = {"version": "2.1.0", "obs_shape": [60, 80, 3], "gl_renderer": "llvmpipe"}
    line = peer.describe(peer.Rounds(ours=[{}, {}], peer=[600.0, 700.0, 650.0], info=info))
    assert "650.0 steps/s" in line and "median of 600.0, 700.0, 650.0" in line and "obs 60x80x3" in line
    line = peer.describe(peer.Rounds(ours=[{}], peer=None, why="no GL here"))
    assert line == f"peer  MiniWorld {peer.PEER_ENV}: NOT MEASURED, no GL here"


class FakeMiniWorld:
    """Stands in for peer.MiniWorld: answers 100, 200, ... steps/s, or fails at the measurement ``fail_at``."""

    fail_at = None
    log: list = []

    def __init__(self, seed, lp_threads=None):
        self.info = {"version": "fake"}
        self.answers = 0

    def measure(self, seconds, warmup):
        if self.answers == self.fail_at:
            raise FakeMiniWorld.unavailable("the fake stopped answering")
        self.answers += 1
        self.log.append(("peer", self.answers))
        return 100.0 * self.answers

    def close(self):
        self.log.append(("closed",))


def test_in_rounds_times_the_peer_before_the_first_round_and_after_each(peer, monkeypatch):
    FakeMiniWorld.unavailable, FakeMiniWorld.log, FakeMiniWorld.fail_at = peer.PeerUnavailable, [], None
    monkeypatch.setattr(peer, "MiniWorld", FakeMiniWorld)

    def measure_round(i):
        FakeMiniWorld.log.append(("ours", i))
        return {"rate": 10.0 * (i + 1)}

    result = peer.in_rounds(2, measure_round, seconds=1.0, warmup=0.0, seed=0)
    expected = [("peer", 1), ("ours", 0), ("peer", 2), ("ours", 1), ("peer", 3), ("closed",)]
    assert FakeMiniWorld.log == expected
    assert result.ours == [{"rate": 10.0}, {"rate": 20.0}] and result.peer == [100.0, 200.0, 300.0]
    assert result.info == {"version": "fake"} and result.why is None

    FakeMiniWorld.log, FakeMiniWorld.fail_at = [], 2  # answers twice, then fails: our rounds go on without it
    result = peer.in_rounds(3, measure_round, seconds=1.0, warmup=0.0, seed=0)
    assert [entry[0] for entry in FakeMiniWorld.log].count("ours") == 3
    assert result.peer is None and result.why == "the fake stopped answering" and len(result.ours) == 3


def test_in_rounds_goes_on_when_the_peer_cannot_start(peer, monkeypatch):
    def cannot_start(seed, lp_threads=None):
        raise peer.PeerUnavailable("no GL here")

    monkeypatch.setattr(peer, "MiniWorld", cannot_start)
    result = peer.in_rounds(2, lambda i: i, seconds=1.0, warmup=0.0, seed=0)
    assert result.ours == [0, 1] and result.peer is None and result.why == "no GL here"
    monkeypatch.setattr(peer, "MiniWorld", lambda *args: pytest.fail("MiniWorld started with skip"))
    result = peer.in_rounds(2, lambda i: i, seconds=1.0, warmup=0.0, seed=0, skip=True)
    assert result.ours == [0, 1] and result.peer is None and result.why == "skipped (--no-peer)"


def test_miniworld_child_process_measures_or_says_why(peer):
    if importlib.util.find_spec("miniworld") is None:  # the bench extra is not installed (as in CI)
        with pytest.raises(peer.PeerUnavailable, match=r"pip install miniworld==2\.1\.0"):
            peer.MiniWorld(seed=0)
    else:
        with peer.MiniWorld(seed=0) as miniworld:
            assert miniworld.measure(seconds=0.3, warmup=0.1) > 0 and miniworld.measure(0.2, 0.0) > 0
            assert miniworld.info["obs_shape"] == [60, 80, 3]


def test_env_speed_judges_the_goals_on_the_median_of_the_bracketed_rounds():
    env_speed = load_script("env_speed")
    rounds = [
        {"aec_v0": 50.0, "core_n64_v0": 330.0, "aec_v1": 100.0, "core_n64_v1": 400.0},
        {"aec_v0": 120.0, "core_n64_v0": 250.0, "aec_v1": 90.0, "core_n64_v1": 300.0},
        {"aec_v0": 110.0, "core_n64_v0": 290.0, "aec_v1": 95.0, "core_n64_v1": 320.0},
    ]
    per_round, medians, goals = env_speed.summarise(rounds, [100.0, 100.0, 100.0, 100.0], versions=(0, 1))
    assert per_round["aec_v0"] == [0.5, 1.2, 1.1] and per_round["core_n64_v0"] == [3.3, 2.5, 2.9]
    assert medians["aec_v0"] == 1.1 and medians["core_n64_v0"] == 2.9 and medians["core_n64_v1"] == 3.2
    assert goals == {
        "v0 aec >= 1x MiniWorld": True,
        "v0 core N=64 >= 3x MiniWorld": False,
        "v1 aec >= 1x MiniWorld": False,
        "v1 core N=64 >= 3x MiniWorld": True,
    }
    assert env_speed.summarise(rounds, None) == ({}, {}, {})


def test_train_speed_combines_a_methods_rounds():
    train_speed = load_script("train_speed")
    base = {"num_envs": 16, "rollout_length": 16}
    results = [
        base | {"frames_per_s": fps, "iterations": 2, "frames": 1536, "seconds": s, "collect_s": 1.0, "learn_s": s - 1}
        for fps, s in ((500.0, 3.0), (400.0, 4.0), (450.0, 3.5))
    ]
    combined = train_speed.combine(results)
    assert combined["frames_per_s"] == 450.0 and combined["frames_per_s_rounds"] == [500.0, 400.0, 450.0]
    assert combined["iterations"] == 6 and combined["frames"] == 3 * 1536 and combined["seconds"] == 10.5
    assert combined["frames_per_iteration"] == 768 and combined["num_envs"] == 16
    per_round, medians, goals = train_speed.summarise([{"meta": r} for r in results], [500.0] * 4)
    assert per_round == {"meta": [1.0, 0.8, 0.9]} and medians == {"meta": 0.9}
    assert list(goals.values()) == [False, False]


def test_train_speed_parts_time_every_part_within_the_collections_and_restore_the_library():
    from activeperc_env.core import Simulator
    from activeperc_rl.models import Head

    module = load_script("train_speed")
    methods = ("move", "look", "reset", "render", "look_views")
    originals = [getattr(Simulator, name) for name in methods] + [Head.forward]
    result = module.bench_method("meta", num_envs=2, seconds=0.01, warmup_iters=0, parts=True)
    assert [getattr(Simulator, name) for name in methods] + [Head.forward] == originals
    assert result["iterations"] == 1 and result["frames"] == 3 * 8 * 2  # meta: three rollouts of 8 cycles, 2 rooms
    parts = result["parts_s"]
    assert list(parts) == list(module.PART_LABELS)
    assert all(parts[part] > 0 for part in ("move", "look", "render", "look_views", "forward"))
    assert sum(parts.values()) < result["collect_s"] < result["seconds"]


def test_train_speed_reports_the_parts_of_every_round_without_the_peer(capsys):
    argv = ["--methods", "fixed_forward", "--num-envs", "2", "--seconds", "0.01", "--warmup-iters", "0"]
    report = load_script("train_speed").main([*argv, "--rounds", "2", "--no-peer", "--parts"])
    result = report["methods"]["fixed_forward"]
    assert len(result["frames_per_s_rounds"]) == 2 and result["iterations"] == 2  # one iteration a round
    assert result["parts_s"]["render"] > 0 and report["miniworld_error"] == "skipped (--no-peer)"
    assert set(report["goals_met"].values()) == {None}
    out = capsys.readouterr().out
    assert "parts fixed_forward: collection" in out and "the rest (TorchRL, tensordict, sampling)" in out
    assert "goal  meta >= 1.0x MiniWorld raw env speed on 2 cores: UNKNOWN" in out


def test_train_speed_times_each_method_with_options_changed_in_the_same_rounds(capsys, tmp_path):
    argv = ["--methods", "fixed_forward", "--num-envs", "2", "--seconds", "0.01", "--warmup-iters", "0"]
    argv += ["--rounds", "1", "--no-peer", "--out", str(tmp_path / "speed.json")]
    report = load_script("train_speed").main([*argv, "--variant", "reuse_features=false", "rollout_length=4"])
    assert list(report["methods"]) == ["fixed_forward", "fixed_forward [reuse_features=False] [rollout_length=4]"]
    assert report["methods"]["fixed_forward [reuse_features=False] [rollout_length=4]"]["frames_per_iteration"] == 8
    report = load_script("train_speed").main([*argv, "--flip", "reuse_features"])
    assert list(report["methods"]) == ["fixed_forward", "fixed_forward [reuse_features=False]"]
    assert "gain  fixed_forward" in capsys.readouterr().out
    saved = json.loads((tmp_path / "speed.json").read_text())
    assert saved["command"].endswith("--flip reuse_features") and saved["methods"] == report["methods"]


def test_train_speed_parts_need_the_rooms_in_this_process(capsys):
    with pytest.raises(SystemExit):
        load_script("train_speed").main(["--parts", "--collector", "inprocess", "process"])
    assert "--parts times the rooms of this process" in capsys.readouterr().err


def test_view_profile_times_every_part_and_culls_without_changing_a_pixel():
    result = load_script("view_profile").profile(views=30, seed=0)
    assert result["same_pixels"] and result["boxes"] == 8  # four walls, the goal, three occluders
    assert 0 < result["boxes_drawn_when_culled"] < 8
    parts = ("context", "pose", "scene", "draw", "read")
    assert all(result[mode][part] > 0 for mode in ("whole", "culled") for part in parts)


def table_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith("|")]


def test_compile_speed_times_both_batches_eager_and_compiled_in_every_round(capsys):
    """A collection step's and an update's batch of the default recipe, each timed in both modes in each round."""
    load_script("compile_speed").main(["--rounds", "2", "--seconds", "0.01", "--threads", "1"])
    out = capsys.readouterr().out
    assert "collection step (forward), batch 32:" in out and "update (forward, backward), batch 512:" in out
    assert len(re.findall(r"^  eager [0-9.]+ ms, compiled [0-9.]+ ms a pass$", out, flags=re.MULTILINE)) == 4
    assert len(re.findall(r"compiled / eager passes a second: [0-9.]+x \(rounds [0-9.]+x, [0-9.]+x\)", out)) == 2


def test_portable_speed_trains_each_mode_alike_in_every_round(capsys):
    """Every mode trains, and a mode's runs in two rounds save the same networks (one digest each)."""
    speed = load_script("portable_speed")
    speed.main(["--method", "fixed_forward", "--frames", "512", "--rounds", "2"])
    rows = {line.split("|")[1].strip(): line.split("|")[4].strip() for line in table_lines(capsys.readouterr().out)}
    assert set(speed.MODES) == {"default", "onednn", "portable"} <= set(rows)
    assert all(len(rows[mode].split(", ")) == 1 for mode in speed.MODES), rows


def test_portable_bits_adds_this_vendors_digests_beside_the_others(tmp_path, monkeypatch, capsys):
    """Each candidate's digests are stored under this CPU's vendor, other vendors' kept, and the table says where
    two vendors' digests differ."""
    bits = load_script("portable_bits")
    results = tmp_path / "portable_bits.json"
    other = {"fixed_forward": "0123456789abcdef", "pins": bits.CANDIDATES["portable"][0]}
    old = {"fixed_forward": "0123456789abcdef"}  # stored before the pins were: not compared
    results.write_text(json.dumps({"portable": {"OtherVendor": other}, "unfused_adam": {"OldVendor": old}}))
    monkeypatch.setattr(bits, "RESULTS", results)
    monkeypatch.setattr(bits.golden, "TRAINING_METHODS", ("fixed_forward",))
    flags = ("--portable", "--frames", "512", "--learner-threads", "1", "--torch-threads", "1", "--eval-episodes", "0")
    monkeypatch.setattr(bits.golden, "TRAINING_FLAGS", (*flags, "--no-progress"))
    bits.main(["--only", "portable", "unfused_adam"])
    stored, vendor = json.loads(results.read_text()), bits.cpu_vendor()
    assert set(stored) == {"portable", "unfused_adam"}
    assert set(stored["portable"]) == {"OtherVendor", vendor} and set(stored["unfused_adam"]) == {"OldVendor", vendor}
    rows = {line.split("|")[1].strip(): line.split("|")[-2].strip() for line in table_lines(capsys.readouterr().out)}
    assert rows["portable"] == "no" and rows["unfused_adam"] == "made with other pins"


def with_qemu(bits, monkeypatch) -> None:
    """Make portable_bits find qemu-x86_64 without running it: the tests fake the training (and QEMU's log), so they
    need no emulator (benchmarks/portable_bits.py says how to install one for the real runs)."""
    monkeypatch.setattr(bits.golden.shutil, "which", lambda name: f"/usr/bin/{name}")


def test_portable_bits_stores_an_emulated_cpus_digests_under_its_name(tmp_path, monkeypatch, capsys):
    """--emulate trains under QEMU's CPU (the training is faked here) and files the digests under that CPU's name."""
    bits = load_script("portable_bits")
    monkeypatch.setattr(bits, "RESULTS", tmp_path / "portable_bits.json")
    with_qemu(bits, monkeypatch)
    asked = []
    monkeypatch.setattr(bits, "train", lambda candidate, method, out, emulate, log: asked.append(emulate) or "f" * 16)
    bits.main(["--only", "portable", "--emulate", "Haswell-v4"])
    assert set(asked) == {"Haswell-v4"}
    assert set(json.loads((tmp_path / "portable_bits.json").read_text())["portable"]) == {"emulated Haswell-v4"}
    assert capsys.readouterr().out.startswith("# emulated Haswell-v4")
    with pytest.raises(ValueError, match="give its pins too"):
        bits.golden.train_portable("meta", tmp_path / "run", emulate="Haswell-v4")
    assert bits.golden.emulated(None) == []
    monkeypatch.setattr(bits.golden.shutil, "which", lambda name: None)
    with pytest.raises(SystemExit):
        bits.main(["--only", "portable", "--emulate", "Haswell-v4"])
    assert "emulating Haswell-v4 needs QEMU's user mode" in capsys.readouterr().err


# QEMU's in_asm log as it writes it: a long instruction's last bytes on a line of their own, code translated twice,
# an instruction cut where QEMU's own disassembler gave up (rcpps: 0f 53 c1), a byte no x86-64 CPU runs (06)
IN_ASM_LOG = """----------------
IN:
0x4010977f20:  0f 52 e0                 rsqrtps  %xmm0, %xmm4
0x4010977f23:  66 0f 1f 84 00 00 00 00  nopw     (%rax, %rax)
0x4010977f2b:  00
0x4010977f2c:  d9 fe                    fsin
----------------
IN:
0x4010977f20:  0f 52 e0                 rsqrtps  %xmm0, %xmm4
0x4010977f40:  c4 e2 79 b8 c1           vfmadd231ps %xmm1, %xmm0, %xmm0
----------------
IN:
0x7f0000007000:  0f                       .byte    0x0f
0x7f0000007001:  53 c1                    pushq    %rbx
0x7f0000007003:  06                       .byte    0x06
"""


def test_portable_bits_census_counts_the_cpu_defined_instructions_by_address(tmp_path, monkeypatch, capsys):
    """--census files, beside each run's digest, how many distinct addresses of QEMU's translated code hold each
    instruction whose result the CPU model defines, how many hold any and how many bytes did not disassemble; a
    rerun of the same runs without it keeps the census; it needs --emulate."""
    bits = load_script("portable_bits")
    monkeypatch.setattr(bits, "RESULTS", tmp_path / "portable_bits.json")
    with_qemu(bits, monkeypatch)

    def train(candidate, method, out, emulate, log):
        log.write_text(IN_ASM_LOG)  # as QEMU does, into a folder that exists before the run
        return "f" * 16

    monkeypatch.setattr(bits, "train", train)
    bits.main(["--only", "portable", "--emulate", "Haswell-v4", "--census"])
    entry = json.loads((tmp_path / "portable_bits.json").read_text())["portable"]["emulated Haswell-v4"]
    counts = {"translated": 5, "undecoded": 1, "rsqrtps": 1, "fsin": 1, "rcpps": 1}
    assert entry["census"] == {method: counts for method in bits.golden.TRAINING_METHODS}
    monkeypatch.setattr(bits, "train", lambda candidate, method, out, emulate, log: "f" * 16)
    bits.main(["--only", "portable", "--emulate", "Haswell-v4"])  # the same runs again: their census is kept
    assert json.loads((tmp_path / "portable_bits.json").read_text())["portable"]["emulated Haswell-v4"] == entry
    with pytest.raises(SystemExit):
        bits.main(["--only", "portable", "--census"])
    assert "--census reads QEMU's log of the code it translates: give --emulate CPU too" in capsys.readouterr().err
    monkeypatch.setattr(bits.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(SystemExit):
        bits.main(["--only", "portable", "--emulate", "Haswell-v4", "--census"])
    assert "--census disassembles with capstone: pip install capstone" in capsys.readouterr().err
    (tmp_path / "empty.log").write_text("qemu-x86_64: warning: TCG doesn't support requested feature\n")
    with pytest.raises(ValueError, match="holds no code QEMU translated"):
        bits.census(tmp_path / "empty.log")


def test_the_committed_census_holds_what_training_md_says_of_it():
    """Under the emulated Haswell the check's portable runs train the committed weights and reach no CPU-defined
    instruction in code that disassembled whole, and the control reaches rsqrtps (docs/tables.py writes the counts
    into docs/training.md)."""
    bits = load_script("portable_bits")
    stored, trained = json.loads(bits.RESULTS.read_text()), json.loads(bits.golden.TRAINING.read_text())
    portable, control = (stored[c]["emulated Haswell-v4"]["census"] for c in ("portable", "unfused_adam"))
    assert all(counts["undecoded"] == 0 for counts in (*portable.values(), *control.values()))
    assert all(set(portable[m]) == {"translated", "undecoded"} for m in bits.golden.TRAINING_METHODS)
    assert all(set(control[m]) - {"translated", "undecoded"} == {"rsqrtps"} for m in bits.golden.TRAINING_METHODS)
    for method in bits.golden.TRAINING_METHODS:
        assert stored["portable"]["emulated Haswell-v4"][method] == trained[method]["weights"]
    assert all(control[m]["rsqrtps"] > 0 for m in control)


def test_portable_ops_adds_this_machines_digests_and_names_the_operations_that_differ(tmp_path, monkeypatch, capsys):
    """Digests are taken in a pinned process, stored under this machine's name beside other machines', and an
    operation whose digests differ is marked."""
    ops = load_script("portable_ops")
    results = tmp_path / "portable_ops.json"
    results.write_text(json.dumps({"Other machine": {"sqrt": "0123456789abcdef"}}))
    monkeypatch.setattr(ops, "RESULTS", results)
    ops.main([])
    stored = json.loads(results.read_text())
    (ours,) = set(stored) - {"Other machine"}
    assert {"sqrt", "adam_fused", "network_aten_fused", "views"} <= set(stored[ours])
    rows = {line.split("|")[1].strip(): line.split("|")[-2].strip() for line in table_lines(capsys.readouterr().out)}
    assert rows["sqrt"] == "no" and rows["adam_fused"] == "one machine so far"
    ops.main([])  # a second run replaces this machine's digests with the same ones
    assert json.loads(results.read_text())[ours] == stored[ours]
    ops.main(["--without", "GALLIUM_DRIVER"])  # one pin left out: another machine's name, the same torch kernels
    stored = json.loads(results.read_text())
    assert stored[f"{ours}, without GALLIUM_DRIVER"]["sqrt"] == stored[ours]["sqrt"]
    from activeperc_env import EnvConfig, Simulator

    sim = Simulator(EnvConfig(), num_envs=1)
    drawn_by = load_script("env_speed").gl_renderer_name(sim)
    sim.close()
    if "llvmpipe" in drawn_by:  # Mesa draws here (not a GPU's driver): the pin chose softpipe over llvmpipe
        assert stored[f"{ours}, without GALLIUM_DRIVER"]["views"] != stored[ours]["views"]


def test_warp_profile_splits_a_cycle_and_times_the_device_parts(tmp_path, capsys):
    pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")
    out = tmp_path / "profile.csv"
    argv = ["--device", "cpu", "--num-envs", "2", "--seconds", "0.2", "--warmup", "0", "--repeats", "1"]
    (row,) = load_script("warp_profile").main([*argv, "--csv", str(out)])
    assert row["cycles_per_s"] > 0 and row["move_ms"] > 0 and row["render_ms"] > 0
    assert row["device_physics_ms"] > 0 and row["device_render_ms"] > 0
    assert row["device_mib_per_room"] is None  # Warp's CPU device reports no free memory
    with open(out, newline="") as file:
        (written,) = list(csv.DictReader(file))
    assert int(written["num_envs"]) == 2 and written["device_mib_per_room"] == ""


def test_time_to_success_scores_each_step_over_seeds_and_resumes_where_it_stopped(tmp_path, capsys):
    """Each method and seed trains in steps, each step scored on held-out layouts and written as it finishes; a second
    call trains nothing it has; the report names each threshold per method and the figure is written."""
    tts = load_script("time_to_success")
    tiny = ["--frames", "200", "--num-envs", "4", "--rollout-length", "8", "--max-cycles", "12", "--channels", "8"]
    args = ["--seeds", "0", "1", "--every", "100", "--episodes", "4", "--runs", str(tmp_path / "runs")]
    args += ["--csv", str(tmp_path / "tts.csv"), "--", *tiny, "--hidden-size", "32", "--no-progress"]
    assert tts.main(args) == 0
    rows = tts.read_rows(tmp_path / "tts.csv")
    assert [(r["method"], r["seed"]) for r in rows[::2]] == [("meta", "0"), ("meta", "1")] + [
        ("fixed_forward", "0"),
        ("fixed_forward", "1"),
    ]
    assert all(int(a["frames"]) >= 100 and int(b["frames"]) >= 200 for a, b in zip(rows[::2], rows[1::2], strict=True))
    assert all(r["episodes"] == "4" and 0.0 <= float(r["success_rate"]) <= 1.0 for r in rows)
    out = capsys.readouterr().out
    for method in ("meta", "fixed_forward"):
        for threshold in tts.THRESHOLDS:
            assert f"{method}: mean held-out success {threshold:.2f}: " in out
        assert f"{method}: at 2" in out  # the last point every seed has (200 frames or more)
    assert (tmp_path / "tts.png").stat().st_size > 0
    assert tts.main(args) == 0  # everything measured: nothing trains again
    again = capsys.readouterr().out
    assert "activeperc-train:" not in again
    assert tts.report(rows, ["meta", "fixed_forward"]) in out and tts.report(rows, ["meta", "fixed_forward"]) in again
    assert tts.read_rows(tmp_path / "tts.csv") == rows
    more = ["--seeds", "0", "1", "2", "--no-train", "--figure", str(tmp_path / "drawn.png")]
    assert tts.main([*more, *args[3:]]) == 0  # seed 2 is not measured, and not trained
    assert "activeperc-train:" not in capsys.readouterr().out and (tmp_path / "drawn.png").stat().st_size > 0


def test_time_to_success_keeps_the_rows_another_run_wrote_to_its_csv(tmp_path):
    """Two runs of the benchmark (other seeds, one core each) share a CSV: each row is added to what is there."""
    tts = load_script("time_to_success")
    row = dict.fromkeys(tts.COLUMNS, "x")
    path = tmp_path / "new" / "tts.csv"
    assert tts.add_row(path, row | {"seed": "0"}) == [row | {"seed": "0"}]
    other = tts.add_row(path, row | {"seed": "1"})  # the other run's, written after this one read the CSV
    assert tts.add_row(path, row | {"seed": "2"}) == [*other, row | {"seed": "2"}]
    assert [r["seed"] for r in tts.read_rows(path)] == ["0", "1", "2"]


def test_time_to_success_stops_when_a_stop_signal_ends_a_step_early(tmp_path, monkeypatch):
    """Training saves its checkpoint and returns early on Ctrl-C or SIGTERM: the benchmark stops there, scoring
    nothing."""
    tts = load_script("time_to_success")

    def stopped_training(config, out, resume, progress, stop_at):
        out.mkdir(parents=True)
        (out / tts.METRICS).write_text("frames,time_s\n64,1.0\n")

    monkeypatch.setattr("activeperc_rl.train.train", stopped_training)
    with pytest.raises(SystemExit, match="stopped at 64 of 100 frames"):
        tts.main(["--every", "100", "--runs", str(tmp_path / "runs"), "--csv", str(tmp_path / "tts.csv")])
    assert not (tmp_path / "tts.csv").exists()


def test_time_to_success_refuses_a_training_flag_it_cannot_use(capsys):
    with pytest.raises(SystemExit):
        load_script("time_to_success").main(["--", "--epsilon", "0.1", "--method", "fixed_forward"])
    assert "--epsilon is not an option of method 'fixed_forward'" in capsys.readouterr().err


def test_view_parallel_times_one_thread_two_threads_and_two_processes(capsys):
    """Each round names the three ways with their views/s, and the two ways of two with their ratio to one thread's."""
    load_script("view_parallel").main(["--views", "4", "--seconds", "0.5", "--rounds", "1"])
    out = capsys.readouterr().out
    assert "LP_NUM_THREADS=" in out and "4 views of the default room" in out
    pattern = r"round 1: one thread [0-9,]+ views/s; two threads, a context each, [0-9,]+ \([0-9.]+x\); two processes"
    assert re.search(pattern + r" [0-9,]+ \([0-9.]+x\)$", out, flags=re.MULTILINE), out
