"""``uav-swarm simulate``: the main job. Fly the placement planner over a dynamic crowd sequence.

Runs ``uav_swarm_v0`` (waypoint mode) for ``duration_s`` of simulated time with the learned planner
(utility network -> peaks -> Hungarian), replanning every ``--replan-every-steps`` steps, then the same
sequence (same seed, same crowd) with the expert planner, and writes into ``--out``: ``qos.png``,
``scene.gif``, ``summary.json``, ``timeseries.csv`` and ``missions/vehicle_<id>.plan``. Telemetry
(UAV states, plans, QoS) goes out over Zenoh on tcp/127.0.0.1:7447 unless ``--no-telemetry``.

Examples:
  uav-swarm simulate --out out/sim
  uav-swarm simulate --out out/sim --duration-s 60 --n-uavs 6 --seed 3 --no-gif
  uav-swarm simulate --out out/sim --checkpoint runs/s1/train/best.pt --config sim.toml
  uav-swarm simulate --out out/sim --bridge-config configs/bridge/px4_sitl_10.toml   # upload the missions
  uav-swarm simulate --out out/sim --record out/sim/run.mcap   # open it in Foxglove
  uav-swarm simulate --out out/sim --live 8765 --live-wait-s 120 --speedup 1   # watch it in Foxglove
  uav-swarm simulate --out out/sim --ros2   # on ROS 2: RViz, Foxglove, operator targets (docs/ros2.md)

Telemetry left at its default endpoint moves to a free port of 127.0.0.1 when another run holds
tcp/127.0.0.1:7447, and says where; an endpoint given in --config ([telemetry] listen) is used as given.

Exit codes: 0 done, 1 upload failed (outputs written), 2 bad configuration, checkpoint, output path,
telemetry endpoint given in --config (e.g. "tcp/127.0.0.1:7447 is in use") or live view address, found
before the first step and before any output; 130 interrupted (nothing written).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from uav_swarm.cli.conventions import config_flag, number, output_flag, run_folder_flag

if TYPE_CHECKING:
    from uav_swarm.runs.fly_config import FlyConfig
    from uav_swarm.runs.simulate_config import SimulateConfig

__all__ = ["register", "run", "format_summary", "wrote_line", "telemetry_endpoint", "CHECKPOINT_HELP"]

logger = logging.getLogger(__name__)

RunConfig = TypeVar("RunConfig", "SimulateConfig", "FlyConfig")

CHECKPOINT_HELP = ("learned planner checkpoint (default: the shipped one for the task: "
                   "wifi-s<strategy>-80211.pt under the 802.11 radio, the default; on the paper's radio "
                   "wifi-s1.pt for strategy 1, wifi-s2-ac.pt for strategy 2 under admission control, "
                   "wifi-s2.pt for strategy 2 with station_limit = \"off\"); one trained for another radio, "
                   "strategy or admission is refused)")


NEXT_STEPS = ("next: uav-swarm fly --simulated ardupilot --duration-s 60 --speedup 2 --out out/fly flies "
              "this planner on 5 simulated ArduCopters (about 70 s)\n"
              "next: uav-swarm telemetry watch in a second terminal shows the next run live; what each "
              "figure means: docs/simulate.md")
"""What to try after the demo: two lines printed at the end of a finished run."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` subcommand."""
    parser = subparsers.add_parser(
        "simulate", help="the main job: fly the planner over a crowd sequence, compare with the expert",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    cfg = "uav_swarm.runs.simulate_config:SimulateConfig."
    run_folder_flag(parser, "--out", default="out/simulate", help="output folder")
    add("--config", type=Path, help="TOML of SimulateConfig (keys and tables [task], [uav], [planning], "
                                    "[telemetry]); flags override it (default: none, the defaults below)")
    config_flag(parser, "--planner", cfg + "planner", choices=("learned", "expert"))
    add("--checkpoint", help=CHECKPOINT_HELP)
    add("--refine", action="store_true", help="refine the learned peaks on the crowd ([planning] refine)")
    add("--rule-check", action="store_true",
        help="keep the learned peaks the deployment rule justifies on the raster ([planning] rule_check)")
    config_flag(parser, "--duration-s", cfg + "duration_s")
    config_flag(parser, "--n-uavs", cfg + "n_uavs")
    config_flag(parser, "--seed", cfg + "seed")
    config_flag(parser, "--replan-every-steps", cfg + "replan_every", dest="replan_every", metavar="STEPS")
    config_flag(parser, "--bridge-config", cfg + "bridge_config")
    add("--no-expert", action="store_true", help="do not fly the expert on the same sequence")
    add("--no-telemetry", action="store_true", help="do not publish over Zenoh")
    add("--ros2", action="store_true",
        help="publish the run on ROS 2 (/uav_swarm/<swarm>/...) and take operator targets; needs the ros2 "
             "extra; DDS stays on this machine unless [ros2] localhost_only = false (default: off)")
    add("--no-gif", action="store_true", help="do not write scene.gif")
    output_flag(parser, "--record", "file", metavar="RUN.mcap",
        help="record the flown run (scene, UAV states, plans, QoS) as MCAP for Foxglove (default: none)")
    add("--live", metavar="[HOST:]PORT",
        help="stream the flown run to Foxglove (Open connection, Foxglove WebSocket) from a server on this "
             "address; HOST defaults to 127.0.0.1 (this machine only); works with --record (default: none)")
    add("--live-wait-s", type=number(float, ge=0.0), metavar="SECONDS",
        help="with --live: wait at most this long for a Foxglove client before the first step (default: 0)")
    add("--speedup", type=number(float, gt=0.0), metavar="X",
        help="with --live: run X simulated seconds per wall-clock second, to watch (1: the crowd's pace; "
             "default: as fast as it computes)")
    parser.set_defaults(func=run)


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    values = {"planner": args.planner, "checkpoint": args.checkpoint, "duration_s": args.duration_s,
              "n_uavs": args.n_uavs, "seed": args.seed, "replan_every": args.replan_every,
              "bridge_config": args.bridge_config}
    overrides = {key: value for key, value in values.items() if value is not None}
    planning = {key: True for key, on in (("refine", args.refine), ("rule_check", args.rule_check)) if on}
    if planning:
        overrides["planning"] = planning
    if args.no_expert:
        overrides["compare_expert"] = False
    if args.no_telemetry:
        overrides["publish_telemetry"] = False
    if args.ros2:
        overrides["ros2"] = {"enabled": True}
    if args.no_gif:
        overrides["gif"] = False
    return overrides


def telemetry_endpoint(config: RunConfig, config_path: Path | None) -> RunConfig:
    """``config`` with its telemetry moved to a free loopback port when the default one is taken.

    Only an endpoint nobody chose moves: one given in ``config_path`` ([telemetry] listen) is opened as
    given, or refused. The move is logged as a warning naming the new endpoint.
    """
    from bridge.telemetry.config import listen_elsewhere_if_taken
    from typed_config import read_toml

    if not config.publish_telemetry:
        return config
    if config_path is not None and "listen" in read_toml(config_path).get("telemetry", {}):
        return config
    telemetry, line = listen_elsewhere_if_taken(config.telemetry)
    if line is None:
        return config
    logger.warning("%s", line)
    return config.replace(telemetry=telemetry)


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as a small text table (one row per planner, then the ratios).

    The planners in name order and each 802.11 line's users in band order, so that the summary a run
    returns and the same summary read back from ``summary.json`` (written with sorted keys) print the same.
    """
    from uav_swarm.runs.outputs.radio_report import admission_line

    summary = {**summary, "planners": dict(sorted(summary["planners"].items()))}

    header = (f"{'planner':<8} {'QoS S1 mean':>11} {'min':>6} {'QoS S2 mean':>11} {'min':>6} "
              f"{'Mbps mean':>9} {'plan ms p50':>11} {'p95':>8}")
    lines = [header, "-" * len(header)]
    for kind, s in summary["planners"].items():
        lines.append(f"{kind:<8} {s['mean_qos_s1']:>11.3f} {s['min_qos_s1']:>6.3f} {s['mean_qos_s2']:>11.3f} "
                     f"{s['min_qos_s2']:>6.3f} {s['mean_throughput_mbps']:>9.2f} "
                     f"{s['median_latency_ms']:>11.2f} {s['p95_latency_ms']:>8.2f}")
    first: dict[str, Any]  # the first planner's figures (none: an empty table)
    first = next(iter(summary["planners"].values()), {})
    if "radio" in summary:
        lines.append(summary["radio"])
    if "association" in first:
        lines.append(f"radio association: {first['association']}")
        lines.extend(_why_s2_is_low(first, summary.get("config", {}).get("task", {})))
    if "expert" in summary:
        lines.append(f"expert: {summary['expert']}")
    for kind, s in summary["planners"].items():
        if "wifi_80211" in s:
            lines.append(_wifi_line(kind, s["wifi_80211"]))
            if s["wifi_80211"].get("rate_bar", {}).get("admission_on_rate"):  # why QoS S2 is what it is
                lines.append("  " + admission_line(kind, s["wifi_80211"]))
    paper = {kind: s["mean_qos_s2_paper_radio"] for kind, s in summary["planners"].items()
             if "mean_qos_s2_paper_radio" in s}
    if paper:
        lines.append("the same flights, QoS S2 on the paper's radio: "
                     + ", ".join(f"{kind} {value:.3f}" for kind, value in paper.items()))
    for kind, s in summary["planners"].items():
        if s.get("separation"):
            lines.append(_separation_line(kind, s["separation"]))
    ratios = summary.get("ratios_learned_over_expert")
    if ratios:
        def show(value: float | None) -> str:
            return "n/a" if value is None else f"{value:.3f}"

        lines.append(f"learned / expert: QoS S1 {show(ratios['mean_qos_s1'])}, "
                     f"S2 {show(ratios['mean_qos_s2'])}, throughput {show(ratios['mean_throughput_mbps'])}; "
                     f"expert / learned planning time {show(ratios['expert_over_learned_median_latency'])}x")
    if "inference_engine" in summary:
        checkpoint = f"{summary['checkpoint']}, " if "checkpoint" in summary else ""
        lines.append(f"learned network: {checkpoint}{summary['inference_engine']} engine, "
                     f"{summary['network_precision']}")
    return "\n".join(lines)


def _why_s2_is_low(first: dict[str, Any], task: dict[str, Any]) -> list[str]:
    """Where QoS S2 is low by the radio's design, one line saying why (none otherwise).

    The paper's radio shares a UAV's capacity among every user in range; under 802.11 strategy 1 admits
    every user in range however slow its share of the airtime.
    """
    association, radio = first["association"], task.get("radio", {})
    strategy = task.get("strategy", 1)
    if association.startswith("802.11") and strategy == 1 and "admission on rate" not in association:
        rate = radio.get("min_user_rate_mbps", 5.0)
        return [f"  strategy 1 refuses no user on rate: every user in range shares its access point's "
                f"airtime (mean {first['mean_throughput_mbps']:.2f} Mbps per user), so QoS S2 stays low "
                f"(strategy 2 admits a user only while all keep {rate:g} Mbps)"]
    if not association.startswith("paper") or "capacity_mbps" not in radio:
        return []
    capacity, rate = radio["capacity_mbps"], radio["min_user_rate_mbps"]
    aim = "strategy 1 places for S1; " if strategy == 1 else ""
    return [f"  on this radio every user in range shares its UAV's {capacity:g} Mbps: over "
            f"{capacity / rate:.0f} users a UAV gives each under {rate:g} Mbps, so QoS S2 stays low ({aim}"
            "admission control: docs/admission.md)"]


def wrote_line(files: list[str], out: Path) -> str:
    """The files a run wrote, those in a folder counted by folder.

    Examples:
        >>> wrote_line(["qos.png", "missions/vehicle_1.plan", "missions/vehicle_2.plan", "summary.json"],
        ...            Path("out"))
        'wrote qos.png, summary.json, missions/ (2 files) in out'
    """
    top = [name for name in files if "/" not in name]
    folders: dict[str, int] = {}
    for name in files:
        if "/" in name:
            folder = name.split("/", 1)[0]
            folders[folder] = folders.get(folder, 0) + 1
    counted = [f"{folder}/ ({n} file{'' if n == 1 else 's'})" for folder, n in folders.items()]
    return f"wrote {', '.join(top + counted)} in {out}"


def _wifi_line(kind: str, wifi: dict[str, Any]) -> str:
    """One planner's 802.11 figures: SINR, MCS shares, final channels, co-channel sharing."""
    sinr = "n/a" if wifi["median_sinr_db"] is None else f"{wifi['median_sinr_db']:.1f} dB"
    from uav_swarm.runs.outputs.radio_report import MCS_BANDS

    order = {name: rank for rank, (name, _, _) in enumerate(MCS_BANDS)}
    bands = sorted(wifi["mcs_shares"].items(), key=lambda item: order.get(item[0], len(order)))
    shares = ", ".join(f"{name} {share:.0%}" for name, share in bands)
    pairs = "; ".join(f"{p['uavs'][0]}-{p['uavs'][1]} {p['seconds']:.1f} s" for p in wifi["co_channel_pairs"])
    return (f"{kind} 802.11: median SINR {sinr}; users {shares}; channels {wifi['channels_final']} "
            f"({wifi['channel_changes']} changes); co-channel pairs sharing airtime: "
            f"{pairs or 'none'}")


def _separation_line(kind: str, figures: dict[str, Any]) -> str:
    """One planner's separation: the closest pair (which, when), conflicts, time below the minimum, holds."""
    if figures["closest_m"] is None:
        closest = "no pair flew"
    else:
        first, second = figures["closest_pair"]
        closest = (f"closest pair {figures['closest_m']:.2f} m (UAVs {first} and {second} at "
                   f"{figures['closest_t_s']:.1f} s)")
    return (f"{kind} separation (minimum {figures['min_separation_m']:g} m): {closest}, "
            f"{figures['conflicts']} conflicts, {figures['time_below_min_s']:.1f} s below the minimum, "
            f"{figures['holds']} holds")


def run(args: argparse.Namespace) -> int:
    """Validate the configuration, run the job, print the summary table.

    The line saying what it waits for comes once the configuration is valid (bad input gets its one line
    alone), before the heavy imports of the run itself.
    """
    from bridge.errors import BridgeError
    from bridge.telemetry.config import TelemetryConnectionError
    from learning.checkpoint import CheckpointError
    from typed_config import ConfigError
    from uav_swarm.runs.outputs.live_view import live_view_option
    from uav_swarm.runs.simulate_config import load_simulate_config

    try:
        live = live_view_option(args.live, args.live_wait_s, args.speedup)
        config = telemetry_endpoint(load_simulate_config(args.config, _overrides(args)), args.config)
        print(f"uav-swarm simulate: loading the planners, then flying {config.duration_s:g} s of crowd time "
              f"(minutes) into {args.out}; Ctrl-C keeps the part flown", flush=True)
        from uav_swarm.runs.simulate import simulate

        result = simulate(config, args.out, progress=not args.quiet, record=args.record, live=live)
    except (ConfigError, CheckpointError) as exc:
        print(f"uav-swarm simulate: {exc}", file=sys.stderr)
        return 2
    except TelemetryConnectionError as exc:
        print(f"uav-swarm simulate: {exc}; use --no-telemetry, or another [telemetry] listen endpoint",
              file=sys.stderr)
        return 2
    except BridgeError as exc:
        if isinstance(exc, ValueError):
            print(f"uav-swarm simulate: {exc}", file=sys.stderr)
            return 2
        bridge = args.bridge_config or "the bridge config"
        print(f"uav-swarm simulate: the upload failed: {exc}; the run and its missions are written in "
              f"{args.out}: start the vehicles of {bridge} (SITL, real autopilots, or simulated ones in "
              f"another terminal: uav-swarm vehicles --bridge-config {bridge}), then uav-swarm mission "
              f"upload --config {bridge} --from-dir {args.out / 'missions'}", file=sys.stderr)
        return 1
    summary = result.summary
    print(f"uav_swarm_v0: {config.n_uavs} UAVs, {summary['planners'][config.planner]['n_pedestrians']} "
          f"pedestrians, {summary['duration_s']:.0f} s simulated, replan every {config.replan_every} steps, "
          f"seed {config.seed}")
    print(format_summary(summary))
    print("QoS S1/S2, the static reference, holds and the planner's names: docs/glossary.md")
    files = summary["files"]
    print(wrote_line(files, args.out))
    if "recording" in summary:
        print(f"recorded the {config.planner} planner's run in {summary['recording']}")
    cut = summary.get("interrupted")
    if cut is not None:
        print(f"uav-swarm simulate: interrupted (Ctrl-C) at {cut['at_s']:g} s of the {cut['planner']} "
              f"planner's run: the figures and files above cover {cut['kept']}", file=sys.stderr)
        return 130
    print(NEXT_STEPS)
    return 0
