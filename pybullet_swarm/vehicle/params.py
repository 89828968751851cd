"""Airframe parameters, read by name from the YAML file beside each URDF."""
from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Literal

import numpy as np
import pydantic
from numpy.typing import NDArray

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.resources import bundled_vehicles, urdf_dir
from pybullet_swarm.validation import read_yaml, validate


class _VehicleFile(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", frozen=True)

    name: str
    urdf: str
    mass: float = pydantic.Field(gt=0)
    inertia: tuple[pydantic.PositiveFloat, pydantic.PositiveFloat, pydantic.PositiveFloat]
    arm_length: float = pydantic.Field(gt=0)
    configuration: Literal["x", "plus"] = "x"
    kf: float = pydantic.Field(gt=0)
    km: float = pydantic.Field(gt=0)
    motor_time_constant: float = pydantic.Field(gt=0)
    max_rotor_speed: float = pydantic.Field(gt=0)
    collision_size: tuple[pydantic.PositiveFloat, pydantic.PositiveFloat, pydantic.PositiveFloat]


@dataclasses.dataclass(frozen=True)
class VehicleParams:
    """Physical parameters of one airframe (SI units).

    Rotor numbering (X configuration, seen from above, x forward, y left): 0 front-left,
    1 back-left, 2 back-right, 3 front-right. Rotors 0 and 2 spin counter-clockwise, 1 and 3
    clockwise, so that the drag torques cancel at hover.
    """

    name: str
    urdf_path: Path
    mass: float                          # kg
    inertia: tuple[float, float, float]  # kg m^2, principal moments (x, y, z)
    arm_length: float                    # m, centre to rotor axis
    configuration: str                   # 'x' or 'plus'
    kf: float                            # thrust coefficient, N/(rad/s)^2
    km: float                            # drag-torque coefficient, N m/(rad/s)^2
    motor_time_constant: float           # s
    max_rotor_speed: float               # rad/s
    collision_size: tuple[float, float, float]  # m, box extents (x, y, z)
    param_file: Path | None = None       # the YAML these parameters were read from (for error messages)

    @property
    def rotor_xy(self) -> NDArray[np.float64]:
        """Rotor positions in the body frame, (4, 2) m."""
        base = np.pi / 4 if self.configuration == "x" else 0.0
        ang = base + np.arange(4) * np.pi / 2  # 0 front-left (x), counter-clockwise
        return self.arm_length * np.stack([np.cos(ang), np.sin(ang)], axis=1)

    @property
    def spin(self) -> NDArray[np.float64]:
        """Rotor spin directions, (4,): +1 counter-clockwise seen from above, -1 clockwise."""
        return np.array([1.0, -1.0, 1.0, -1.0])

    @property
    def mixer(self) -> NDArray[np.float64]:
        """Map squared rotor speeds (rad/s)^2 to [thrust N, tau_x, tau_y, tau_z N m], (4, 4).

        A rotor spinning counter-clockwise drags the body clockwise: its yaw torque is -km w^2.
        """
        xy = self.rotor_xy
        return np.stack([
            np.full(4, self.kf),
            self.kf * xy[:, 1],
            -self.kf * xy[:, 0],
            -self.km * self.spin,
        ])

    @functools.cached_property
    def mixer_inverse(self) -> NDArray[np.float64]:
        """Map [thrust, tau_x, tau_y, tau_z] to squared rotor speeds, (4, 4)."""
        return np.linalg.inv(self.mixer)

    @property
    def weight(self) -> float:
        """Weight at standard gravity, N (see ``hover_rotor_speed`` for other gravities)."""
        return self.mass * 9.81

    def hover_rotor_speed(self, gravity: float = 9.81) -> float:
        """Rotor speed at which the four rotors carry the weight, rad/s: sqrt(m g / (4 kf))."""
        return float(np.sqrt(self.mass * gravity / (4.0 * self.kf)))

    def thrust_to_weight(self, gravity: float = 9.81) -> float:
        """Maximum total thrust over weight."""
        return 4.0 * self.kf * self.max_rotor_speed**2 / (self.mass * gravity)

    @property
    def radius(self) -> float:
        """Radius of the horizontal circle that encloses the airframe, m."""
        return float(0.5 * np.hypot(self.collision_size[0], self.collision_size[1]))


def _resolve(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    try:
        if p.suffix in (".yaml", ".yml") and p.is_file():
            return p
        candidate = urdf_dir() / f"{name_or_path}.yaml"
        if candidate.is_file():
            return candidate
    except OSError:   # e.g. a name too long for the file system
        pass
    raise ConfigError(
        f"unknown vehicle {str(name_or_path)!r}, expected one of {', '.join(bundled_vehicles())} "
        "or a path to a vehicle .yaml file"
    )


@functools.cache
def _load(path: Path) -> VehicleParams:
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise ConfigError("must be a mapping of vehicle parameters", source=path.name)
    data = validate(_VehicleFile, raw, source=path.name)
    urdf = path.parent / data.urdf
    if not urdf.is_file():
        raise ConfigError(f"URDF file {data.urdf!r} not found beside the parameter file", source=path.name, field="urdf")
    fields = data.model_dump()
    fields.pop("urdf")
    return VehicleParams(urdf_path=urdf, param_file=path, **fields)


def load_vehicle(name_or_path: str | Path) -> VehicleParams:
    """Parameters of a bundled vehicle by name ('quad150', 'cf2x') or of a vehicle YAML file."""
    return _load(_resolve(name_or_path).resolve())
