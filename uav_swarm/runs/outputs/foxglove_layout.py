"""The Foxglove layout for a run, built with the SDK's layout types (``foxglove.layouts``).

Three panels over the channels of :mod:`uav_swarm.runs.outputs.recording`: a 3D view of the ``map`` frame
seen from above (the area and obstacles, the UAVs, their coverage discs and targets on ``/scene``;
the crowd on ``/pedestrians``, coloured by ``covered``; the plan's targets on ``/plan/targets``), a
plot of QoS S1 and S2 with the mean user throughput on a second axis (``/qos``), and the latest plan
as a table (``/plan.targets``). The committed copy is ``docs/foxglove/uav-swarm-layout.json``
(Foxglove: Layouts, Import from file); a test keeps it equal to :func:`layout_json`.

Examples:
    >>> import json
    >>> json.loads(layout_json())["content"]["type"]
    'split'
"""

from __future__ import annotations

import json

import foxglove.layouts as fl

from uav_swarm.runs.outputs.foxglove_scene import MAP_FRAME

__all__ = ["layout", "layout_json"]

_BLUE, _ORANGE, _GREEN = "#1a59d9", "#e6730d", "#2e9e44"


def _three_d() -> fl.ThreeDeePanel:
    crowd = fl.BaseRendererPointCloudTopicSettings(
        visible=True, point_size=6.0, color_mode="gradient", color_field="covered",
        gradient=("#9e9e9eff", "#2e9e44ff"), min_value=0.0, max_value=1.0)
    camera = fl.ThreeDeeCameraState(distance=260.0, perspective=False, phi=0.0, theta_offset=0.0,
                                    target=(100.0, 100.0, 0.0), target_offset=(0.0, 0.0, 0.0),
                                    target_orientation=(0.0, 0.0, 0.0, 1.0), fovy=45.0, near=0.5, far=5000.0)
    config = fl.ThreeDeeConfig(follow_tf=MAP_FRAME, fixed_frame=MAP_FRAME, follow_mode="follow-none",
                               camera_state=camera,
                               topics={"/scene": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                                       "/pedestrians": crowd,
                                       "/plan/targets": fl.BaseRendererPosesTopicSettings(visible=False)})
    return fl.ThreeDeePanel(title="Swarm over the crowd (map frame)", config=config)


def _qos_plot() -> fl.PlotPanel:
    series = [fl.PlotSeries(value="/qos.qos_s1", label="QoS S1 (share served)", color=_BLUE),
              fl.PlotSeries(value="/qos.qos_s2", label="QoS S2", color=_ORANGE),
              fl.PlotSeries(value="/qos.mean_throughput_mbps", label="mean throughput (Mbps)", color=_GREEN,
                            y_axis_id="throughput")]
    config = fl.PlotConfig(paths=series, min_y_value=0.0, max_y_value=1.0, show_legend=True,
                           legend_display="top", x_axis_val="timestamp",
                           secondary_axes=[fl.PlotSecondaryAxis(id="throughput", label="Mbps", min=0.0)])
    return fl.PlotPanel(title="QoS and throughput", config=config)


def _plan_table() -> fl.TablePanel:
    return fl.TablePanel(title="Latest plan: target of each UAV",
                         config=fl.TableConfig(topic_path="/plan.targets"))


def layout() -> fl.Layout:
    """The layout: the 3D view on the left (two thirds), the QoS plot above the plan table on the right."""
    side = fl.SplitContainer(direction="column", items=[fl.SplitItem(proportion=3, content=_qos_plot()),
                                                         fl.SplitItem(proportion=2, content=_plan_table())])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=2, content=_three_d()), fl.SplitItem(proportion=1, content=side)]))


def layout_json() -> str:
    """:func:`layout` as the JSON text of a Foxglove layout file (indented, ending in a newline)."""
    return json.dumps(json.loads(layout().to_json()), indent=2) + "\n"
