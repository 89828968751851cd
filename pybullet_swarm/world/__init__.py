"""The World: the only layer that imports pybullet."""

from pybullet_swarm.world.world import BodyKind, World

__all__ = ["BodyKind", "World"]
