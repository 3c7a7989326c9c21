"""The (α2, σ2) grid search on the synthetic blob task: both executors, resume, reports and errors."""

import functools
import json
import shutil

import numpy as np
import pytest
from blob_task import BlobConfig, BlobTask

from learning.data import generate_dataset, load_arrays
from learning.executors import ray_session as local_ray_session
from learning.model import ModelConfig
from learning.search import SearchError, executor_label, run_search
from learning.search_grid import SearchConfig, parse_grid
from learning.search_report import (
    f1_score,
    heatmap_figure,
    markdown_summary,
    mean_expert_distance_px,
    summarise,
)
from learning.train import TrainConfig
from typed_config import ConfigError
from uav_swarm.cli import build_parser, main
from uav_swarm.cli.conventions import iter_parsers
from uav_swarm.missions import registry

SMALL = functools.partial(BlobTask, BlobConfig(size_px=16, max_blobs=3))
MODEL = ModelConfig(width=4)
TRAIN = TrainConfig(epochs=2, batch_size=8, max_steps=3, val_fraction=0.25, device="cpu")
GRID = SearchConfig(alpha2="10:20:10", sigma2="2:4:2")


class Killed(Exception):
    pass


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("data")
    generate_dataset(SMALL, 24, 5, out, shard_size=12, workers=1, progress=False)
    return out


@pytest.fixture(scope="module")
def local_run(data, tmp_path_factory):
    out = tmp_path_factory.mktemp("local")
    return out, search(data, out)


def search(data, out, train=TRAIN, config=GRID, **kwargs):
    kwargs.setdefault("workers", 1)
    return run_search(data, out, config, model_config=MODEL, train_config=train, **kwargs)


def scores(out):
    trials = json.loads((out / "search.json").read_text())["trials"]
    return {(t["alpha2"], t["sigma2"]): (t["corr"], t["precision"], t["val_loss"], t["steps"])
            for t in trials}


def test_local_search_trains_every_point_and_reports(data, local_run):
    out, summary = local_run
    result = scores(out)
    assert sorted(result) == [(10, 2), (10, 4), (20, 2), (20, 4)]
    assert all(steps == 3 for *_, steps in result.values())
    assert len({loss for _, _, loss, _ in result.values()}) == 4  # each point trained on its own targets
    corr = {point: c for point, (c, *_) in result.items()}
    assert summary["corr"] == [[corr[10, 2], corr[10, 4]], [corr[20, 2], corr[20, 4]]]
    assert summary["best"]["corr"] == max(corr.values())
    assert summary["alpha2_rise_pts"] == pytest.approx(100 * (max(corr.values()) - min(corr.values())))
    _, arrays = load_arrays(data)
    rule = summary["rule_of_thumb"]
    assert rule["alpha2"] == pytest.approx(mean_expert_distance_px(arrays["positions"], arrays["mask"]) / 4)
    assert summary["budget"]["max_steps"] == 3 and summary["budget"]["n_val"] == 6
    assert "3 steps run" in (out / "summary.md").read_text()
    assert (out / "heatmap.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "trials" / "a20_s4" / "checkpoint.pt").exists()
    assert not list(out.glob(".*.tmp"))


@pytest.fixture(scope="module")
def ray_session():
    import ray
    assert not ray.is_initialized()
    with local_ray_session(num_cpus=2, object_store_memory=100 * 2**20, logging_level="ERROR"):
        yield


def test_ray_tune_gives_the_same_numbers_as_local(data, local_run, ray_session, tmp_path):
    summary = search(data, tmp_path, executor="ray", workers=None)
    assert scores(tmp_path) == scores(local_run[0])
    assert summary["corr"] == local_run[1]["corr"] and summary["executor"] == "ray"
    assert (tmp_path / "ray").is_dir()  # Tune's storage stays under the output folder


def test_killed_search_resumes_in_a_process_pool_without_redoing_finished_trials(data, local_run, tmp_path):
    def kill(trial):
        raise Killed

    with pytest.raises(Killed):
        search(data, tmp_path, on_trial=kill)
    first = scores(tmp_path)
    assert len(first) == 1
    ran = []
    search(data, tmp_path, on_trial=ran.append, workers=2)  # the remaining trials, two processes at once
    assert len(ran) == 3 and set(first).isdisjoint((t["alpha2"], t["sigma2"]) for t in ran)
    assert scores(tmp_path) == scores(local_run[0])
    ran.clear()
    search(data, tmp_path, on_trial=ran.append)
    assert ran == []


def test_interrupted_trial_continues_from_its_checkpoint(data, local_run, tmp_path):
    one = SearchConfig(alpha2="20", sigma2="4")
    search(data, tmp_path, config=one)
    checkpoint = tmp_path / "trials" / "a20_s4" / "checkpoint.pt"
    stamp = checkpoint.stat().st_mtime_ns
    (tmp_path / "search.json").unlink()  # killed after the training, before its result was recorded
    search(data, tmp_path, config=one)
    assert checkpoint.stat().st_mtime_ns == stamp  # nothing trained again
    assert scores(tmp_path) == {(20, 4): scores(local_run[0])[20, 4]}


def test_results_of_another_budget_or_dataset_are_refused(data, local_run, tmp_path_factory):
    out = local_run[0]
    with pytest.raises(SearchError, match=r"train_config\.max_steps = 3 there, 2 now"):
        search(data, out, train=TRAIN.replace(max_steps=2))
    other = tmp_path_factory.mktemp("other-data")
    generate_dataset(SMALL, 24, 6, other, shard_size=12, workers=1, progress=False)
    with pytest.raises(SearchError, match=r"data\.seed = 5 there, 6 now"):
        search(other, out)
    with pytest.raises(SearchError, match="val_fraction"):
        search(data, out, train=TRAIN.replace(val_fraction=0.0))


def test_best_by_f1_charges_for_peaks_that_match_no_expert():
    # (20, 2) has the highest correspondence but sprays peaks; (10, 4) is the best trade-off.
    table = {(10, 2): (0.50, 0.50), (10, 4): (0.60, 0.70), (20, 2): (0.70, 0.15), (20, 4): (0.40, 0.20)}
    trials = [{"alpha2": float(a), "sigma2": float(s), "corr": c, "precision": p, "train_s": 1.0}
              for (a, s), (c, p) in table.items()]
    manifest = {"task": "blob", "n": 24, "seed": 5, "split": "train", "shape": [16, 16]}
    summary = summarise(GRID, trials, manifest, 8.0, {"text": "3 steps"}, "local")
    assert (summary["best"]["alpha2"], summary["best"]["sigma2"]) == (20, 2)
    assert (summary["best_f1"]["alpha2"], summary["best_f1"]["sigma2"]) == (10, 4)
    assert summary["best_f1"]["f1"] == pytest.approx(2 * 0.6 * 0.7 / 1.3)
    assert summary["f1"][1][0] == pytest.approx(2 * 0.7 * 0.15 / 0.85)
    assert "best (α2, σ2) by F1 of correspondence and precision: (10, 4)" in markdown_summary(
        {**summary, "threads_per_trial": 1, "total_train_s": 4.0})
    assert f1_score(np.zeros(2), np.zeros(2)).tolist() == [0.0, 0.0]


def test_grids_parse_inclusively():
    assert parse_grid("20:60:10", "alpha2") == (20, 30, 40, 50, 60)
    assert parse_grid("0.1:0.3:0.1", "sigma2") == (0.1, 0.2, 0.3)
    assert parse_grid("40", "alpha2") == (40,)
    assert SearchConfig().points[:2] == [(20, 5), (20, 15)] and len(SearchConfig().points) == 25


def test_the_command_line_default_grid_is_the_readmes_wifi_grid():
    parser = build_parser()
    args = parser.parse_args(["search", "--task", "wifi-s1", "--data", "d", "--out", "o"])
    assert (args.alpha2, args.sigma2) == (None, None)  # not given: SearchConfig's defaults, as the help says
    assert (SearchConfig().alpha2, SearchConfig().sigma2) == ("20:60:10", "5:45:10")
    search_help = " ".join(dict(iter_parsers(parser))[("search",)].format_help().split())
    assert "(default: 20:60:10)" in search_help and "(default: 5:45:10)" in search_help
    assert SearchConfig().sigma2_values == (5, 15, 25, 35, 45)


def _trials(out):
    return json.loads((out / "search.json").read_text())["trials"]


def _set_executors(out, executor, drop=None):
    """Rewrite search.json as if its trials had run on ``executor`` (None: not recorded), less ``drop``."""
    saved = json.loads((out / "search.json").read_text())
    trials = [t for t in saved["trials"] if (t["alpha2"], t["sigma2"]) != drop]
    for t in trials:
        t.pop("executor", None)
        if executor is not None:
            t["executor"] = executor
    (out / "search.json").write_text(json.dumps({**saved, "trials": trials}))


def test_a_resumed_search_names_the_executors_its_trials_ran_on(data, local_run, tmp_path):
    assert {t["executor"] for t in _trials(local_run[0])} == {"local"}
    out = tmp_path / "search"
    shutil.copytree(local_run[0], out)
    _set_executors(out, "ray")  # every trial ran on Ray; this re-run only writes the report
    summary = search(data, out)
    assert summary["executor"] == "ray" and "executor: ray," in (out / "summary.md").read_text()
    _set_executors(out, "ray", drop=(20, 4))  # one trial is run again, here
    summary = search(data, out)
    assert summary["executor"] == "local + ray"
    assert {(t["alpha2"], t["sigma2"]): t["executor"] for t in _trials(out)}[20, 4] == "local"
    assert json.loads((out / "summary.json").read_text())["executor"] == "local + ray"


def test_trials_recorded_before_executors_were_keep_the_reports_executor(data, local_run, tmp_path):
    out = tmp_path / "search"
    shutil.copytree(local_run[0], out)
    _set_executors(out, None)
    summary_path = out / "summary.json"
    summary_path.write_text(json.dumps({**json.loads(summary_path.read_text()), "executor": "ray"}))
    assert search(data, out)["executor"] == "ray"
    assert {t["executor"] for t in _trials(out)} == {"ray"}
    _set_executors(out, None)
    summary_path.unlink()
    assert search(data, out)["executor"] == "unrecorded"
    assert executor_label([{"executor": "ray"}, {"executor": "local"}]) == "local + ray"


@pytest.mark.parametrize("shape", [(5, 1), (1, 1), (2, 2), (5, 5)], ids=["5x1", "1x1", "2x2", "5x5"])
def test_the_heat_map_title_is_whole_on_any_grid(shape):
    alphas, sigmas = [20.0 + 10 * i for i in range(shape[0])], [5.0 + 10 * j for j in range(shape[1])]
    corr = np.linspace(0.2, 0.9, shape[0] * shape[1]).reshape(shape)
    point = {"alpha2": alphas[-1], "sigma2": sigmas[0], "corr": 0.9, "precision": 0.5, "f1": 0.6}
    summary = {"task": "wifi-s2-with-a-long-name", "grid": {"alpha2": alphas, "sigma2": sigmas},
               "corr": corr.tolist(), "best": point, "best_f1": {**point, "alpha2": alphas[0]},
               "alpha2_rise_pts": 70.0, "budget": {"steps_run": 300, "batch_size": 16, "n_train": 3600}}
    fig = heatmap_figure(summary)
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    frame = fig.bbox
    title = " ".join(t.get_text().replace("\n", " ") for t in fig.texts)
    assert "α2-rise +70.0 pts" in title and "on 3600 scenes" in title and "wifi-s2-with-a-long-name" in title
    for text in fig.texts:
        box = text.get_window_extent(renderer)
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1, (
            shape, box, frame)


@pytest.mark.parametrize(("field", "text", "message"), [
    ("alpha2", "60:20:10", r"SearchConfig\.alpha2 = '60:20:10' is an empty range"),
    ("sigma2", "20:60:0", r"SearchConfig\.sigma2 .*step = 0 must be > 0"),
    ("sigma2", "20:60:-10", r"SearchConfig\.sigma2 .*step = -10 must be > 0"),
    ("sigma2", "-10:20:10", r"SearchConfig\.sigma2 .*must be > 0"),
    ("sigma2", "0:20:10", r"SearchConfig\.sigma2 .*must be > 0"),
    ("alpha2", "-10:20:10", r"SearchConfig\.alpha2 .*must be >= 0"),
    ("alpha2", "20-60", r"SearchConfig\.alpha2 = '20-60' must be 'start:stop:step'"),
    ("alpha2", "20:60", r"SearchConfig\.alpha2 = '20:60' must be 'start:stop:step'"),
], ids=["empty", "zero-step", "negative-step", "negative-sigma", "zero-sigma", "negative-alpha", "dash",
        "two-parts"])
def test_invalid_grids_are_clear_errors(field, text, message):
    with pytest.raises(ConfigError, match=message):
        SearchConfig(**{field: text})


def test_search_command_generates_data_and_resumes(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(registry.TASKS, "blobs", registry.TaskEntry("blob_task:BlobTask"))
    config = tmp_path / "blobs.toml"
    config.write_text("[task]\nsize_px = 16\n[model]\nwidth = 4\n[train]\nbatch_size = 8\ndevice = 'cpu'\n")
    args = ["search", "--task", "blobs", "--config", str(config), "--data", str(tmp_path / "data"),
            "--n", "12", "--seed", "2", "--out", str(tmp_path / "out"), "--alpha2", "5:10:5", "--sigma2", "3",
            "--epochs", "1", "--max-steps", "1", "--workers", "1"]
    assert main(args) == 0
    assert "best (α2, σ2)" in capsys.readouterr().out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["grid"] == {"alpha2": [5, 10], "sigma2": [3], "rows": "alpha2", "columns": "sigma2"}
    assert main([*args[:-6], "--epochs", "2", "--max-steps", "1"]) == 2  # another budget, same folder
    assert "train_config.epochs = 1 there, 2 now" in capsys.readouterr().err
    assert main([*args[:13], "--sigma2", "0:3:1"]) == 2
    assert np.isfinite(summary["alpha2_rise_pts"])
