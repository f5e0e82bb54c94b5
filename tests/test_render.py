"""The tiled renderer draws the same pixels as one view at a time, and the map shows the scene."""

import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import assert_same_view

import activeperc_env
from activeperc_env import EnvConfig, Simulator


def test_tiled_views_equal_single_views():
    many = Simulator(num_envs=7)
    many.reset(seeds=np.arange(7))
    many.move(np.arange(7) % 3)
    many.look((np.arange(7) + 1) % 3)
    tiled = many.render()
    for i in range(7):
        assert_same_view(many.render(ids=[i])[0], tiled[i])


def test_a_map_drawn_between_views_changes_no_pixel():
    """The maps have a buffer of their own: a map drawn before, between or after views leaves every view and map as
    it is drawn alone."""
    with_maps, alone = (Simulator(num_envs=3) for _ in range(2))
    for sim in (with_maps, alone):
        sim.reset(seeds=[4, 5, 6])
    first_map = with_maps.render_map(1)
    assert np.array_equal(with_maps.render(), alone.render())
    for sim in (with_maps, alone):
        sim.move(np.array([0, 1, 2]))
    between = with_maps.render_map(1)
    assert np.array_equal(with_maps.render(), alone.render())
    assert np.array_equal(between, alone.render_map(1)) and not np.array_equal(first_map, between)
    with_maps.close()
    alone.close()


def test_views_span_several_buffer_passes():
    config = EnvConfig(width=512, height=384)
    sim = Simulator(config, num_envs=120)  # more tiles than one 4096x4096 buffer holds
    assert sim.renderer.cols * sim.renderer.rows < 120
    sim.reset(seeds=np.arange(120) % 3)
    images = sim.render()
    assert_same_view(images[0], images[117])
    assert not np.array_equal(images[0], images[1])


def test_goal_is_red_and_fov_widens_the_view():
    narrow, wide = Simulator(EnvConfig(fov=60, num_obstacles=0)), Simulator(EnvConfig(fov=100, num_obstacles=0))
    reds = []
    for sim in (narrow, wide):
        sim.reset(seeds=[0])
        xy, heading, _ = sim.pose()
        to_goal = sim.goal_xy() - xy
        bearing = np.arctan2(to_goal[1], to_goal[0]) - heading
        steps = int(np.round(np.degrees(bearing) / sim.config.pan_step))
        for _ in range(abs(steps)):  # point the camera at the goal
            sim.look([0 if steps > 0 else 2])
        image = sim.render()[0].astype(int)
        reds.append(((image[..., 0] > 120) & (image[..., 1] < 60) & (image[..., 2] < 60)).sum())
    assert reds[0] > 0 and reds[1] > 0
    assert reds[0] > reds[1], "the same goal fills fewer pixels of a wider view"


def test_map_shows_goal_and_occluders():
    sim = Simulator()
    sim.reset(seeds=[0])
    image = sim.render_map().astype(int)
    red = (image[..., 0] > 150) & (image[..., 1] < 60) & (image[..., 2] < 60)
    blue = (image[..., 2] > 150) & (image[..., 0] < 80)
    assert red.sum() > 50 and blue.sum() > 50


def test_map_shows_every_wall_whole():
    """The walls' outer faces (x = -+3.1 m, y = -+2.1 m) lie inside the map, with a margin of background around."""
    sim = Simulator()
    sim.reset(seeds=[7])
    image = sim.render_map().astype(int)
    wall = (image > 200).all(axis=-1)
    background = (image == 0).all(axis=-1)
    middle_row, middle_column = image[120], image[:, 160]
    for line, outer in ((middle_row, 160 - 3.1 * 50), (middle_column, 120 - 2.1 * 50)):
        edge = int(round(outer))
        inside = (line[edge : edge + 5] > 200).all(axis=-1)
        beyond = (line[:edge] == 0).all(axis=-1)
        assert inside.all() and beyond.all() and edge >= 5, (edge, line[: edge + 5].tolist())
    assert (wall[:, ::-1] == wall).mean() > 0.99 and (wall[::-1] == wall).mean() > 0.99  # the room is centred
    assert background[:5].all() and background[:, :5].all() and background[-5:].all() and background[:, -5:].all()


def test_map_is_north_up_with_the_view_cone_where_the_camera_looks():
    """The map's camera sees 4.8 m of the room's height on 240 rows (50 pixels a metre), centred on the room, +x
    right and +y up; the cone shows where the camera looks, a white line the base's heading."""
    sim = Simulator(EnvConfig(pan_step=90.0))
    sim.reset(seeds=[3])
    sim.look([2])  # the camera turns 90 degrees to the right of the heading

    def pixel(xy):  # (row, column) of a point of the floor
        scale = 240 / 4.8
        return np.array([120 - xy[1] * scale, 160 + xy[0] * scale])

    image = sim.render_map().astype(int)
    red = (image[..., 0] > 150) & (image[..., 1] < 60) & (image[..., 2] < 60)
    assert np.abs(np.argwhere(red).mean(axis=0) - pixel(sim.goal_xy())).max() < 3
    xy, heading, pan = sim.pose()
    assert pan == pytest.approx(-np.pi / 2)
    orange = (image[..., 0] > 200) & (image[..., 1] > 90) & (image[..., 1] < 180) & (image[..., 2] < 60)
    along = np.argwhere(orange).mean(axis=0) - pixel(xy)  # from the robot to the middle of the cone's edges
    look = np.array([-np.sin(heading + pan), np.cos(heading + pan)])  # (rows, columns) per metre, up to the scale
    assert orange.sum() > 20 and along @ look / np.linalg.norm(along) > 0.9
    white = (image > 230).all(axis=-1)

    def white_near(point):
        row, column = np.round(pixel(point)).astype(int)
        return white[row - 2 : row + 3, column - 2 : column + 3].any()

    forward = np.array([np.cos(heading), np.sin(heading)])
    assert white_near(xy + 0.4 * forward) and not white_near(xy - 0.4 * forward)


FORK_SCRIPT = """
import multiprocessing, sys
from activeperc_env import Simulator

def child(queue):
    try:
        sim = Simulator(num_envs=1)
        sim.reset(seeds=[1])
        queue.put(("rendered", sim.render().shape))
    except RuntimeError as error:
        queue.put(("error", str(error)))

if sys.argv[1] == "after-render":
    parent = Simulator(num_envs=1)
    parent.reset(seeds=[0])
    parent.render()
context = multiprocessing.get_context("fork")
queue = context.Queue()
process = context.Process(target=child, args=(queue,), daemon=True)  # a hung child dies with the script
process.start()
print(queue.get(timeout=60))
process.join()
"""


@pytest.mark.parametrize("parent", ["after-render", "before-render"])
def test_a_fork_of_a_rendering_process_fails_clearly_instead_of_hanging(parent):
    """The GL driver hangs when a forked child makes a context after its parent made one: the child gets a
    RuntimeError that says to spawn instead. A fork taken before the parent rendered renders as usual."""
    done = subprocess.run(
        [sys.executable, "-c", FORK_SCRIPT, parent], capture_output=True, text=True, timeout=120, check=True
    )
    if parent == "after-render":
        assert "('error'," in done.stdout and "'spawn'" in done.stdout
    else:
        assert done.stdout.strip() == "('rendered', (1, 60, 80, 3))"


def test_llvmpipe_without_threads_draws_the_same_pixels(tmp_path):
    """activeperc_env sets LP_NUM_THREADS=0; docs/performance.md suggests threads for large batches: same pixels."""
    script = (
        "import sys, numpy as np\n"
        "from activeperc_env import Simulator\n"
        "sim = Simulator(num_envs=5)\n"
        "sim.reset(seeds=np.arange(5))\n"
        "sim.move(np.arange(5) % 3)\n"
        "np.save(sys.argv[1], np.concatenate([sim.render(), sim.render_map(2)[None, :60, :80]]))\n"
    )
    pixels = {}
    for threads in ("0", "2"):
        env = {**os.environ, "LP_NUM_THREADS": threads}
        path = tmp_path / f"pixels_{threads}.npy"
        subprocess.run([sys.executable, "-c", script, str(path)], env=env, check=True, timeout=120)
        pixels[threads] = np.load(path)
    assert pixels["0"].any() and np.array_equal(pixels["0"], pixels["2"])


@pytest.mark.parametrize("num_obstacles", [0, 3])
def test_parked_occluders_left_out_of_the_views_change_no_pixel(num_obstacles):
    """load_model hides the occluders a config leaves parked; drawing them must give exactly the same pixels."""
    import mujoco

    from activeperc_env import names

    hidden, drawn = (Simulator(EnvConfig(num_obstacles=num_obstacles, pan_range=120), num_envs=6) for _ in range(2))
    parked = [mujoco.mj_name2id(drawn.model, mujoco.mjtObj.mjOBJ_GEOM, b) for b in names.OCCLUDER_BODIES]
    parked = parked[num_obstacles:]
    assert (hidden.model.geom_group[parked] == names.HIDDEN_GROUP).all()
    drawn.model.geom_group[parked] = 0
    rng = np.random.default_rng(num_obstacles)
    for sim in (hidden, drawn):
        sim.reset(seeds=np.arange(6))
    for _ in range(40):  # moves into walls and corners, looks all around
        moves, looks = rng.integers(0, 3, 6), rng.integers(0, 3, 6)
        for sim in (hidden, drawn):
            sim.move(moves)
            sim.look(looks)
        assert np.array_equal(hidden.render(), drawn.render())
        assert np.array_equal(hidden.render_map(1), drawn.render_map(1))
        for sim in (hidden, drawn):
            if sim.done.any():
                sim.reset(np.flatnonzero(sim.done))


@pytest.mark.skipif(os.environ.get("MUJOCO_GL") != "egl", reason="reads the current context through EGL")
def test_a_renderer_frees_its_gl_objects_in_its_own_context():
    """MuJoCo frees a renderer's framebuffer and textures by their names in whatever GL context is current. Freed
    under another renderer's context, they deleted that renderer's objects of the same names: an env whose earlier
    copy was collected while the env's context was current drew wrong views from then on."""
    from OpenGL import EGL

    old, new = Simulator(), Simulator()
    for sim in (old, new):
        sim.reset(seeds=[0])
        sim.render()
    renderer = old.renderer
    ours = renderer._gl.context._context.address
    current = []

    class Spy:
        def __init__(self, context):
            self.context = context

        def free(self):
            current.append(EGL.eglGetCurrentContext().address)
            self.context.free()

    renderer._ctx = Spy(renderer._ctx)
    old.close()
    assert current == [ours]
    before = new.render().copy()
    new.set_state(new.get_state())  # draw anew
    assert_same_view(new.render(), before)
    new.close()


def test_an_env_renders_in_whichever_thread_steps_it():
    """An env made and reset in one thread and stepped in another (a thread pool, an evaluation thread) draws as in
    one thread: each draw releases its GL context (EGL refused a context still current in the thread that drew
    last: EGL_BAD_ACCESS)."""
    import threading

    actions = [{"mover_0": m, "looker_0": c} for m, c in [(2, 2), (0, 1), (2, 0), (1, 2)]]
    alone = activeperc_env.parallel_env()
    alone.reset(seed=5)
    expected = [alone.step(a)[0]["mover_0"]["image"] for a in actions]
    env = activeperc_env.parallel_env()
    env.reset(seed=5)
    seen = []
    for a in actions:  # each step in a thread of its own, then the main thread renders again
        worker = threading.Thread(target=lambda a=a: seen.append(env.step(a)[0]["mover_0"]["image"]))
        worker.start()
        worker.join()
        env.sim.render()
    assert len(seen) == len(actions)
    for got, want in zip(seen, expected, strict=True):
        np.testing.assert_array_equal(got, want)


@pytest.mark.skipif(os.environ.get("MUJOCO_GL") != "egl", reason="reads the current context through EGL")
def test_a_renderer_closed_in_the_middle_of_anothers_draw_gives_its_context_back():
    """The garbage collector may close an env's renderer while another renderer draws (at any allocation of the
    draw): the drawing one's context must be current again afterwards, or its read-back silently returned its
    previous frame."""
    from OpenGL import EGL

    drawing, collected = Simulator(), Simulator()
    for sim in (drawing, collected):
        sim.reset(seeds=[0])
        sim.render()
    with drawing.renderer._current():
        collected.close()
        assert EGL.eglGetCurrentContext().address == drawing.renderer._gl.context._context.address
    assert not EGL.eglGetCurrentContext()  # and nothing is left current after the draw
    drawing.close()


INHERITED_SCRIPT = """
import multiprocessing, os, sys, time
from activeperc_env import Simulator

sim = Simulator(num_envs=1)
sim.reset(seeds=[0])
sim.render()

def child(queue):
    try:
        sim.move([2])
        queue.put(("rendered", sim.render().shape))
    except RuntimeError as error:
        queue.put(("error", str(error)))

if sys.argv[1] == "step":
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    process = context.Process(target=child, args=(queue,), daemon=True)
    process.start()
    print(queue.get(timeout=60))
    process.join()
else:  # a plain os.fork child that exits normally, running the exit handlers it inherited
    pid = os.fork()
    if pid == 0:
        sys.exit(0)
    for _ in range(300):
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            print("child exited", os.waitstatus_to_exitcode(status))
            break
        time.sleep(0.1)
    else:
        print("child hung")
        os.kill(pid, 9)
print("parent renders", sim.render().shape)
"""


@pytest.mark.parametrize("child", ["step", "exit"])
def test_a_fork_that_inherited_a_rendering_env_neither_hangs_nor_breaks_the_parent(child):
    """Stepping the inherited env fails clearly (it hung in the read-back); a fork that just exits does (it hung in
    MuJoCo's exit handler, which terminated the EGL display the parent's driver state was copied from)."""
    done = subprocess.run(
        [sys.executable, "-c", INHERITED_SCRIPT, child], capture_output=True, text=True, timeout=120, check=True
    )
    if child == "step":
        assert "('error'," in done.stdout and "'spawn'" in done.stdout, done.stdout
    else:
        assert "child exited 0" in done.stdout, done.stdout
    assert "parent renders (1, 60, 80, 3)" in done.stdout


def test_video_frames_have_even_sides_and_fit_any_view():
    """H.264 needs even sides; a view taller than the map is shown whole (a config may ask for up to 1024 rows)."""
    from activeperc_env.render import side_by_side

    map_image = np.full((240, 320, 3), 7, np.uint8)
    odd = side_by_side(map_image, np.full((61, 81, 3), 9, np.uint8))  # scaled 3x: 183 rows, 243 columns
    assert odd.shape == (240, 320 + 244, 3)
    assert (odd[:183, 320:563] == 9).all() and (odd[183:, 320:] == 0).all() and (odd[:, 563:] == 0).all()
    tall = side_by_side(map_image, np.full((300, 64, 3), 9, np.uint8))
    assert tall.shape == (300, 384, 3) and (tall[:240, :320] == 7).all() and (tall[240:, :320] == 0).all()
