"""RViz / Foxglove markers of a foothold plan (the gait node's `gait_markers`)."""

from __future__ import annotations

from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from replan_core.common.types import WORLD_FRAME, FootholdPlan
from replan_core.gait.crawl import stance_phases
from replan_ros.messages.stamps import header

# Leg colours of the markers (r, g, b), LEGS order.
_LEG_COLOURS = ((0.9, 0.2, 0.2), (0.2, 0.7, 0.2), (0.2, 0.4, 0.9), (0.9, 0.7, 0.1))
# Support polygon corners in cyclic order around the trunk: lf, rf, rh, lh.
_POLYGON_ORDER = (0, 1, 3, 2)


def gait_markers(plan: FootholdPlan) -> MarkerArray:
    """The plan's initial feet, footholds (paler later) and support polygons (orange: three
    feet, green: four), in the world frame at the plan's start."""
    hdr = header(plan.start_time, WORLD_FRAME)
    markers = [Marker(header=hdr, action=Marker.DELETEALL)]
    feet = Marker(header=hdr, ns='initial_feet', id=0, type=Marker.SPHERE_LIST,
                  action=Marker.ADD)
    feet.scale = Vector3(x=0.05, y=0.05, z=0.05)
    feet.pose.orientation.w = 1.0
    for p in plan.initial_feet:
        feet.points.append(Point(x=float(p[0]), y=float(p[1]), z=float(p[2])))
        feet.colors.append(ColorRGBA(r=0.5, g=0.5, b=0.5, a=1.0))
    markers.append(feet)
    holds = Marker(header=hdr, ns='footholds', id=0, type=Marker.SPHERE_LIST,
                   action=Marker.ADD)
    holds.scale = Vector3(x=0.04, y=0.04, z=0.04)
    holds.pose.orientation.w = 1.0
    for k, step in enumerate(plan.steps):
        r, g, b = _LEG_COLOURS[step.leg]
        holds.points.append(Point(x=float(step.target[0]), y=float(step.target[1]),
                                  z=float(step.target[2])))
        fade = 1.0 - 0.6 * k / max(len(plan.steps), 1)   # later footholds paler
        holds.colors.append(ColorRGBA(r=r, g=g, b=b, a=fade))
    markers.append(holds)
    for k, (_t0, _t1, positions, stance) in enumerate(stance_phases(plan)):
        poly = Marker(header=hdr, ns='support_polygons', id=k, type=Marker.LINE_STRIP,
                      action=Marker.ADD)
        poly.scale.x = 0.005
        poly.pose.orientation.w = 1.0
        three = int(stance.sum()) == 3
        poly.color = (ColorRGBA(r=1.0, g=0.5, b=0.0, a=0.8) if three
                      else ColorRGBA(r=0.1, g=0.8, b=0.3, a=0.5))
        corners = [leg for leg in _POLYGON_ORDER if stance[leg]]
        for leg in [*corners, corners[0]]:
            p = positions[leg]
            poly.points.append(Point(x=float(p[0]), y=float(p[1]),
                                     z=float(p[2]) + 0.002 * k))   # stacked, readable
        markers.append(poly)
    return MarkerArray(markers=markers)
