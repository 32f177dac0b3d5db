"""The stick-figure animation writes a GIF with one frame per frame time, read back with PIL:
at least 720 px wide, the push arrow on every frame of the push (and only then) with a length
proportional to the force, and the motionless end after settling fast-forwarded."""

import numpy as np
import pytest
from margins import within
from PIL import Image, ImageSequence

from mjx_balance.figures import animation as animate
from mjx_balance.model.params import Config
from mjx_balance.reference.loop import simulate_scenario

PUSH_ORANGE = np.array([255, 127, 14])  # the push arrow's colour (matplotlib tab:orange)


def orange_pixels(frame: Image.Image) -> int:
    """Pixels of the push arrow's colour (within the GIF palette's rounding)."""
    rgb = np.asarray(frame.convert("RGB"), dtype=int)
    return int((np.abs(rgb - PUSH_ORANGE).sum(axis=-1) < 60).sum())


def test_frame_times():
    np.testing.assert_allclose(animate.frame_times(0.4, 10.0), np.arange(5) / 10)
    np.testing.assert_allclose(animate.frame_times(0.39, 10.0), [0, 0.1, 0.2, 0.3, 0.39])
    assert animate.frame_times(0.0, 25.0).size == 1
    with pytest.raises(ValueError):
        animate.frame_times(1.0, 0.0)
    # a push shorter than a frame still gets PUSH_FRAMES frames
    times = animate.frame_times(0.4, 10.0, push=0.05)
    assert (times < 0.05).sum() == animate.PUSH_FRAMES and times[-1] == pytest.approx(0.4)


def test_frames_fast_forward_after_settling():
    regular = animate.frame_times(12.0, 25.0)
    assert regular.size == 301
    times = animate.frame_times(12.0, 25.0, settled_at=1.5)
    assert times[0] == 0 and times[-1] == pytest.approx(12.0)
    assert times.size < 0.3 * regular.size
    steps = np.diff(times)
    hold = 1.5 + animate.SETTLED_HOLD_S
    np.testing.assert_allclose(steps[times[1:] <= hold], 1 / 25)  # real time up to then
    assert steps[times[:-1] > hold + 1e-9].max() == pytest.approx(animate.FAST_FORWARD / 25)
    np.testing.assert_allclose(
        animate.frame_times(12.0, 25.0, settled_at=1.5, fast_forward=1), regular
    )


def _gif(tmp_path, force, t_end=0.4, fps=20.0, dpi=40):
    config = Config().replace(scenario={"t_end": t_end})
    summary, ts = simulate_scenario(config, force, 0.1)
    path = tmp_path / f"push_{force:g}.gif"
    frames = animate.animate_timeseries(
        ts, path, config.body, fps=fps, dpi=dpi, summary=summary, scenario=config.scenario
    )
    return ts, path, frames


def test_animation_has_the_expected_frames(tmp_path):
    fps, dpi = 20.0, 40
    ts, path, frames = _gif(tmp_path, 60.0, fps=fps, dpi=dpi)
    expected = animate.frame_times(float(ts.time.iloc[-1]), fps, push=0.1)
    assert frames == expected.size == 11  # t = 0, 1/30, 0.05, 1/15, 0.1, ..., 0.4
    size = (round(animate.FIGSIZE[0] * dpi), round(animate.FIGSIZE[1] * dpi))
    with Image.open(path) as gif:
        assert gif.n_frames == expected.size
        assert gif.size == size == (384, 216)
        orange = []
        for frame in ImageSequence.Iterator(gif):
            assert frame.size == size
            within(
                frame.info.get("duration"),
                1000 / fps,
                atol=1,
                why="a GIF stores a frame's duration in whole hundredths of a second "
                "(Pillow reads it back in ms): 1000 / fps = 50 ms exactly, 1 ms for "
                "a rounding",
            )
            orange.append(orange_pixels(frame))
    # the push arrow is drawn on every frame while the push acts (t < 0.1 s), not after
    pushing = expected < 0.1 - 1e-9
    assert pushing.sum() == 4
    assert all(n > 0 for n in np.array(orange)[pushing]), orange
    assert all(n == 0 for n in np.array(orange)[~pushing]), orange


def test_push_arrow_length_grows_with_the_force(tmp_path):
    def first_frame_orange(force):
        _, path, _ = _gif(tmp_path, force, t_end=0.1, fps=10.0, dpi=60)
        with Image.open(path) as gif:
            return orange_pixels(gif)

    small, large = first_frame_orange(40.0), first_frame_orange(160.0)
    assert large > 2 * small > 0


def test_animate_command(tmp_path, capsys):
    from mjx_balance.cli import main

    path = tmp_path / "cmd.gif"
    assert (
        main(["animate", "--force", "40", "--t-end", "0.2", "--fps", "10", "--out", str(path)]) == 0
    )
    with Image.open(path) as gif:
        assert gif.n_frames == 5  # t = 0, 1/30, 1/15 (the push), 0.1, 0.2
        assert gif.size == (768, 432)  # the default 80 dpi: at least 720 px wide
        assert [f.info.get("duration") for f in ImageSequence.Iterator(gif)] == [100] * 5
    captured = capsys.readouterr()
    assert f"wrote {path} (5 frames at 10 fps)" in captured.out + captured.err
