"""An example pybullet_swarm plug-in: the ``follow_route`` planner (see ``planner.py``)."""

from plugin_planner.planner import FollowRoute, FollowRouteParams

__all__ = ["FollowRoute", "FollowRouteParams"]
