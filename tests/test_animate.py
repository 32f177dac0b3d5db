"""The stick-figure animation writes a GIF with one frame per frame time."""

import numpy as np
import pytest
from PIL import Image

from mjx_balance import animate
from mjx_balance.params import Config
from mjx_balance.reference import simulate_scenario


def test_frame_times():
    np.testing.assert_allclose(animate.frame_times(0.4, 10.0), np.arange(5) / 10)
    assert animate.frame_times(0.39, 10.0).size == 4
    assert animate.frame_times(0.0, 25.0).size == 1
    with pytest.raises(ValueError):
        animate.frame_times(1.0, 0.0)


def test_animation_has_the_expected_frames(tmp_path):
    config = Config().replace(scenario={"t_end": 0.4})
    _, ts = simulate_scenario(config, 60.0, 0.1)
    fps = 20.0
    path = tmp_path / "push.gif"
    frames = animate.animate_timeseries(ts, path, config.body, fps=fps, dpi=40)
    expected = animate.frame_times(float(ts.time.iloc[-1]), fps).size
    assert frames == expected == 9  # t = 0, 0.05, ..., 0.4
    with Image.open(path) as gif:
        assert gif.n_frames == expected
        assert gif.info.get("duration") == pytest.approx(1000 / fps, abs=1)


def test_animate_command(tmp_path):
    from mjx_balance.cli import main

    path = tmp_path / "cmd.gif"
    assert main(["animate", "--force", "40", "--t-end", "0.2", "--fps", "10", "--out",
                 str(path)]) == 0
    with Image.open(path) as gif:
        assert gif.n_frames == 3
