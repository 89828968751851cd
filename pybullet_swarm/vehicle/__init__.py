"""Vehicles: parameters read by name, motor model, rotor forces to body wrench, mixer."""

from pybullet_swarm.vehicle.params import VehicleParams, load_vehicle

__all__ = ["VehicleParams", "load_vehicle"]
