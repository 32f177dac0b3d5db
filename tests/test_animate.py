"""The stick-figure animation writes a GIF with one frame per frame time, read back with PIL."""

import numpy as np
import pytest
from PIL import Image, ImageSequence

from mjx_balance import animate
from mjx_balance.params import Config
from mjx_balance.reference import simulate_scenario

FIGSIZE = (4.5, 5.5)  # inches, animate.animate_timeseries's figure
PUSH_ORANGE = np.array([255, 127, 14])  # the push arrow's colour (matplotlib tab:orange)


def orange_pixels(frame: Image.Image) -> int:
    """Pixels of the push arrow's colour (within the GIF palette's rounding)."""
    rgb = np.asarray(frame.convert("RGB"), dtype=int)
    return int((np.abs(rgb - PUSH_ORANGE).sum(axis=-1) < 60).sum())


def test_frame_times():
    np.testing.assert_allclose(animate.frame_times(0.4, 10.0), np.arange(5) / 10)
    assert animate.frame_times(0.39, 10.0).size == 4
    assert animate.frame_times(0.0, 25.0).size == 1
    with pytest.raises(ValueError):
        animate.frame_times(1.0, 0.0)


def test_animation_has_the_expected_frames(tmp_path):
    config = Config().replace(scenario={"t_end": 0.4})
    _, ts = simulate_scenario(config, 60.0, 0.1)
    fps, dpi = 20.0, 40
    path = tmp_path / "push.gif"
    frames = animate.animate_timeseries(ts, path, config.body, fps=fps, dpi=dpi)
    expected = animate.frame_times(float(ts.time.iloc[-1]), fps)
    assert frames == expected.size == 9  # t = 0, 0.05, ..., 0.4
    size = (round(FIGSIZE[0] * dpi), round(FIGSIZE[1] * dpi))
    with Image.open(path) as gif:
        assert gif.n_frames == expected.size
        assert gif.size == size == (180, 220)
        orange = []
        for frame in ImageSequence.Iterator(gif):
            assert frame.size == size
            assert frame.info.get("duration") == pytest.approx(1000 / fps, abs=1)
            orange.append(orange_pixels(frame))
    # the push arrow is drawn while the push acts (t < 0.1 s: frames at 0 and 0.05 s), not after
    pushing = expected < 0.1
    assert all(n > 0 for n in np.array(orange)[pushing]), orange
    assert all(n == 0 for n in np.array(orange)[~pushing]), orange


def test_animate_command(tmp_path, capsys):
    from mjx_balance.cli import main

    path = tmp_path / "cmd.gif"
    assert main(["animate", "--force", "40", "--t-end", "0.2", "--fps", "10", "--out",
                 str(path)]) == 0
    with Image.open(path) as gif:
        assert gif.n_frames == 3  # t = 0, 0.1, 0.2
        assert gif.size == (360, 440)  # the default 80 dpi
        assert [f.info.get("duration") for f in ImageSequence.Iterator(gif)] == [100] * 3
    assert capsys.readouterr().out.strip() == f"wrote {path} (3 frames at 10 fps)"
