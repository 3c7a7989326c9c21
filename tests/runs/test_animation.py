"""The scene GIF, drawn for people: square map in metres, discs or 802.11 service, legend, title, size."""

from types import SimpleNamespace

import numpy as np
import pytest
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar
from PIL import Image

from typed_config import ConfigError
from uav_swarm.runs.outputs.animation import SceneAnimation, write_scene_gif
from uav_swarm.runs.outputs.radio_report import SERVICE_COLOURS
from uav_swarm.runs.outputs.records import Frame
from uav_swarm.runs.simulate_config import SimulateConfig

OBSTACLES = np.array([[20.0, 30.0, 60.0, 30.0], [150.0, 120.0, 150.0, 180.0]])


def _frames(n_frames, n_uavs=10, n_pedestrians=1500, utility=True, seed=0):
    """A crowd of drifting clusters with UAVs over them (the default run's scale)."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(20.0, 180.0, (12, 2))
    members = rng.integers(0, len(centres), n_pedestrians)
    offsets = rng.normal(0.0, 4.0, (n_pedestrians, 2))
    frames = []
    for k in range(n_frames):
        drift = 15.0 * np.sin(0.1 * k + np.arange(len(centres)))[:, None]
        pedestrians = np.clip(centres[members] + drift[members] + offsets + rng.normal(0, 0.3, offsets.shape),
                              0.0, 200.0)
        uavs = np.clip(centres[:n_uavs] + drift[:n_uavs] + rng.normal(0, 2.0, (n_uavs, 2)), 0.0, 200.0)
        covered = np.linalg.norm(pedestrians[:, None] - uavs[None], axis=-1).min(axis=1) < 30.0
        grid = np.linspace(0.0, 200.0, 64)
        xx, yy = np.meshgrid(grid, grid)  # rows northward, as the planner's utility
        field = sum(np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / 50.0) for x, y in uavs)
        frames.append(Frame(time_s=0.3 * k, pedestrians_m=pedestrians, covered=covered, uavs_m=uavs,
                            targets_m=uavs + 3.0, peaks_m=uavs + 1.0, utility=field if utility else None,
                            qos_s1=float(covered.mean()), qos_s2=0.5 * float(covered.mean())))
    return frames


def test_a_frame_is_a_square_map_in_metres_with_whole_discs_a_legend_and_a_title():
    config = SimulateConfig.from_dict({"task": {"radio": {"propagation": "paper"}}})
    frames = _frames(1)
    animation = SceneAnimation(config, OBSTACLES, 10, utility=True)
    image = animation.draw(frames[0])
    assert image.size == (1000, 560) and image.mode == "RGB"
    scene, panel = animation.figure.axes[:2]
    radius = config.task.radio.coverage_radius_m
    for ax in (scene, panel):  # the same square frame of reference, the discs' margin included
        assert ax.get_xlim() == ax.get_ylim()
        assert ax.get_xlim()[0] <= -radius and ax.get_xlim()[1] >= 200.0 + radius
        assert ax.get_aspect() == 1.0 and "East (m)" in ax.get_xlabel()
    assert scene.get_position().width == pytest.approx(panel.get_position().width)
    labels = [t.get_text() for t in animation.figure.legends[0].get_texts()]
    for name in ("UAV", "UAV target", "covered pedestrian", "uncovered pedestrian", "obstacle",
                 "coverage disc (30 m)", "utility peak"):
        assert any(label.startswith(name) for label in labels), (name, labels)
    title = animation.title.get_text()
    assert title.startswith("t = 0.0 s") and f"S1 = {frames[0].qos_s1:.2f}" in title and "S2 = " in title
    (bar,) = [a for a in scene.artists if isinstance(a, AnchoredSizeBar)]
    assert bar.txt_label.get_text() == "50 m"
    assert "Utility map" in panel.get_title()


def test_under_802_11_each_uav_shows_its_channel_and_the_users_it_serves_in_its_colour():
    config = SimulateConfig()  # the 802.11 radio
    frame = _frames(1, n_uavs=3, n_pedestrians=300)[0]
    distances = np.linalg.norm(frame.pedestrians_m[:, None] - frame.uavs_m[None], axis=-1)
    association = np.where(distances.min(axis=1) < 60.0, distances.argmin(axis=1), -1)
    frame = Frame(**{**vars(frame), "covered": association >= 0, "association": association,
                     "channels": np.array([36, 40, 36])})
    animation = SceneAnimation(config, OBSTACLES, 3, utility=True, wifi=True)
    animation.draw(frame)
    scene = animation.figure.axes[0]
    assert not scene.patches[1:]  # the area's outline only: no coverage disc
    served = association >= 0
    colours = animation._covered.get_facecolor()
    expected = np.array([matplotlib_rgba(SERVICE_COLOURS[k]) for k in association[served]])
    assert len(animation._covered.get_offsets()) == served.sum() and np.allclose(colours, expected)
    assert len(animation._uncovered.get_offsets()) == (~served).sum()
    labels = [t.get_text() for t in scene.texts]
    assert labels == ["ch 36", "ch 40", "ch 36"]
    legend = [t.get_text() for t in animation.figure.legends[0].get_texts()]
    assert "pedestrian served by the UAV of its colour ('ch N': the UAV's channel)" in legend
    assert not any("coverage disc" in label for label in legend)
    assert "served with a usable rate" in animation.title.get_text()


def matplotlib_rgba(colour: str) -> tuple[float, ...]:
    from matplotlib.colors import to_rgba

    return to_rgba(colour)


def test_the_expert_run_shows_the_crowd_density_on_the_right():
    animation = SceneAnimation(SimulateConfig(), OBSTACLES, 3, utility=False)
    animation.draw(_frames(1, n_uavs=3, n_pedestrians=200, utility=False)[0])
    assert "Crowd density" in animation.figure.axes[1].get_title()
    assert not any("utility peak" in t.get_text() for t in animation.figure.legends[0].get_texts())


def test_frames_narrower_than_900_px_are_refused():
    with pytest.raises(ConfigError, match="gif_width_px"):
        SimulateConfig(gif_width_px=600)


def test_the_default_run_s_gif_stays_under_5_mb(tmp_path):
    n = 20  # of the default 100 frames: the size per frame is what counts
    run = SimpleNamespace(planner="learned", frames=_frames(n), obstacles_m=OBSTACLES)
    path = write_scene_gif(run, SimulateConfig(), tmp_path / "scene.gif")
    with Image.open(path) as gif:
        assert gif.n_frames == n and gif.size[0] >= 900
    assert path.stat().st_size * 100 / n <= 5e6
