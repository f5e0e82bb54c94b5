"""``activeperc-episode``: one random episode's map, first-person strip and video."""

import imageio.v3 as iio
import numpy as np
import pytest

from activeperc_env import EnvConfig
from activeperc_env.episode import STRIP_CYCLES, STRIP_GAP, main


def test_episode_writes_map_views_and_video(tmp_path, capsys):
    out = tmp_path / "episode"
    assert main(["--out", str(out), "--seed", "3", "--fov", "100"]) == 0
    printed = capsys.readouterr().out
    cycles = int(printed.split(" in ")[1].split(" cycles")[0])
    assert 1 <= cycles <= EnvConfig().max_cycles
    assert iio.imread(out / "map.png").shape == (240, 320, 3)
    views = iio.imread(out / "views.png")
    assert views.shape == (60, 80 * STRIP_CYCLES + STRIP_GAP * (STRIP_CYCLES - 1), 3)
    assert (views[:, 80 : 80 + STRIP_GAP] == 255).all()  # the views stand apart
    frames = iio.imread(out / "episode.mp4")
    assert frames.shape == (cycles + 1, 240, 320 + 320, 3)  # the map, then the view scaled 4x to its height
    assert iio.immeta(out / "episode.mp4")["fps"] == EnvConfig.control_hz
    assert np.abs(frames[0, :, :320].astype(int) - iio.imread(out / "map.png")).mean() < 10  # lossy video


@pytest.mark.parametrize(
    ("flags", "named"),
    [
        (["--fov", "500"], "fov=500"),
        (["--seed", "-1"], "--seed=-1 is invalid"),
        (["--seed", str(2**63)], f"--seed={2**63} is invalid"),
    ],
)
def test_episode_names_a_bad_option(tmp_path, capsys, flags, named):
    with pytest.raises(SystemExit) as exit:
        main(["--out", str(tmp_path / "episode"), *flags])
    assert exit.value.code == 2
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1, err  # one line, no usage block
    assert not (tmp_path / "episode").exists()


def test_episode_names_an_out_that_is_a_file(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    for out, named in ((tmp_path / "file", "is a file, not a folder"), (tmp_path / "file" / "x", "cannot be made")):
        with pytest.raises(SystemExit) as exit:
            main(["--out", str(out)])
        assert exit.value.code == 2 and named in capsys.readouterr().err


def test_episode_refuses_an_output_that_is_a_folder_before_it_plays(tmp_path, capsys, monkeypatch):
    import activeperc_env.episode as episode

    monkeypatch.setattr(episode, "parallel_env", lambda **kwargs: pytest.fail("played before checking"))
    (tmp_path / "episode" / "episode.mp4").mkdir(parents=True)
    with pytest.raises(SystemExit) as exit:
        main(["--out", str(tmp_path / "episode")])
    assert exit.value.code == 2 and "episode.mp4' is a folder" in capsys.readouterr().err


def test_the_seed_picks_the_layout(tmp_path, capsys):
    maps = {}
    for name, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        assert main(["--out", str(tmp_path / name), "--seed", seed, "--no-video"]) == 0
        maps[name] = iio.imread(tmp_path / name / "map.png")
    assert np.array_equal(maps["a"], maps["b"]) and not np.array_equal(maps["a"], maps["c"])
