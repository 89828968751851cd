"""Airframe parameters, read by name from the YAML file beside each URDF."""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.resources import bundled_vehicles, urdf_dir
from pybullet_swarm.validation import read_yaml, validate
from pybullet_swarm.vehicle.downwash import DownwashParams


# finite numbers in (0, bound]
_UpTo1 = Annotated[float, pydantic.Field(gt=0, le=1.0)]
_UpTo10 = Annotated[float, pydantic.Field(gt=0, le=10.0)]
_UpTo100 = Annotated[float, pydantic.Field(gt=0, le=100.0)]
_UpTo1000 = Annotated[float, pydantic.Field(gt=0, le=1000.0)]
_UpTo1e5 = Annotated[float, pydantic.Field(gt=0, le=1e5)]


#: m/s^2, standard gravity (weights of the drag scaling)
G0 = 9.81
#: s/m, the Crazyflie's linear drag near hover per newton of weight, (xy, z): gym-pybullet-drones' cf2x.urdf
#: drag_coeff_xy 9.1785e-7 and drag_coeff_z 10.311e-7 N/((rad/s) (m/s)), times the four rotors' summed hover
#: speed 6064 rad/s, over the 0.027 kg x 9.81 m/s^2 weight
CF2X_DRAG_PER_WEIGHT = (9.1785e-7 * 6063.6 / (0.027 * G0), 10.311e-7 * 6063.6 / (0.027 * G0))


class _VehicleFile(pydantic.BaseModel):
    """The parameter file beside a URDF; physical ranges wide enough for any small multirotor."""

    model_config = pydantic.ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: Annotated[str, pydantic.Field(min_length=1, max_length=100)]
    urdf: Annotated[str, pydantic.Field(min_length=1, max_length=1000)]
    mass: _UpTo1000  # kg
    inertia: tuple[_UpTo1000, _UpTo1000, _UpTo1000]  # kg m^2, principal moments
    arm_length: _UpTo10  # m
    configuration: Literal["x", "plus"] = "x"
    kf: _UpTo1  # N/(rad/s)^2
    km: _UpTo1  # N m/(rad/s)^2
    motor_time_constant: _UpTo10  # s
    max_rotor_speed: _UpTo1e5  # rad/s
    collision_size: tuple[_UpTo100, _UpTo100, _UpTo100]  # m
    # Rotor size and solidity (the wake model, ``pybullet_swarm.vehicle.downwash``); absent: defaults of
    # ``VehicleParams`` (rotor radius 0.6 arm_length, solidity ``DEFAULT_SOLIDITY``)
    rotor_radius: _UpTo10 | None = None  # m
    rotor_solidity: Annotated[float, pydantic.Field(gt=0, le=1.0)] | None = None  # -, blade area / disc area
    # Linear rotor drag near hover (``pybullet_swarm.vehicle.wind``); absent: the Crazyflie's scaled by weight
    drag_xy: Annotated[float, pydantic.Field(ge=0, le=100.0)] | None = None  # N/(m/s)
    drag_z: Annotated[float, pydantic.Field(ge=0, le=100.0)] | None = None  # N/(m/s)

    @pydantic.model_validator(mode="after")
    def _rotors_fit(self) -> _VehicleFile:
        # neighbouring rotors of an X or + frame are arm_length * sqrt(2) apart
        if self.rotor_radius is not None and self.rotor_radius > self.arm_length / math.sqrt(2.0):
            raise ValueError(
                f"rotor_radius {self.rotor_radius} m: neighbouring rotors would overlap "
                f"(at most arm_length / sqrt(2) = {self.arm_length / math.sqrt(2.0):.4g} m)"
            )
        return self

    @pydantic.field_validator("inertia")
    @classmethod
    def _triangle(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        # principal moments of a rigid body: each at most the sum of the other two
        for k in range(3):
            if value[k] > value[(k + 1) % 3] + value[(k + 2) % 3] * (1 + 1e-9):
                raise ValueError(
                    f"principal moments of a rigid body must each be at most the sum of the other two, "
                    f"got {list(value)}"
                )
        return value


MAX_URDF_BYTES = 10 << 20  # bytes

#: -, rotor solidity of a vehicle file that gives none: two blades of chord 0.19 r at three-quarter radius,
#: 2 c / (pi r) = 0.12, typical of small fixed-pitch propellers (an estimate, not a measurement)
DEFAULT_SOLIDITY = 0.12


def check_urdf(urdf: Path, *, source: str) -> None:
    """Refuse a file that is not a URDF of one rigid body: XML with a ``<robot>`` root, at least one
    ``<link>``, only fixed joints (merged into one body) and mesh files that exist.

    Raises:
        ConfigError: one line naming ``source`` and its ``urdf`` field.
    """
    import xml.etree.ElementTree as ET

    def bad(why: str) -> ConfigError:
        return ConfigError(f"{urdf.name} is not a usable URDF: {why}", source=source, field="urdf")

    try:
        with open(urdf, "rb") as fh:
            raw = fh.read(MAX_URDF_BYTES + 1)
    except OSError as exc:
        raise bad(f"cannot read it ({exc.__class__.__name__})") from None
    if len(raw) > MAX_URDF_BYTES:
        raise bad(f"larger than {MAX_URDF_BYTES >> 20} MiB")
    if b"<!ENTITY" in raw:
        raise bad("XML entities are not accepted")
    try:
        root = ET.fromstring(raw)
    except (ET.ParseError, ValueError) as exc:
        raise bad(f"not well-formed XML ({' '.join(str(exc).split())})") from None
    if root.tag != "robot":
        raise bad(f"its root element must be <robot>, got <{_short_tag(root.tag)}>")
    if root.find("link") is None:
        raise bad("it has no <link>")
    for joint in root.iter("joint"):
        if joint.get("type") != "fixed":
            raise bad(
                f"a vehicle is one rigid body, but joint {joint.get('name')!r} is {joint.get('type')!r} "
                f"(only fixed joints)"
            )
    for mesh in root.iter("mesh"):
        name = mesh.get("filename") or ""
        if name and "://" not in name and not (urdf.parent / name).is_file():
            raise bad(f"mesh file {name!r} not found")


def _short_tag(tag: str) -> str:
    return tag if len(tag) <= 40 else tag[:37] + "..."


@dataclasses.dataclass(frozen=True)
class VehicleParams:
    """Physical parameters of one airframe (SI units).

    Rotor numbering (X configuration, seen from above, x forward, y left): 0 front-left,
    1 back-left, 2 back-right, 3 front-right. Rotors 0 and 2 spin counter-clockwise, 1 and 3
    clockwise, so that the drag torques cancel at hover.
    """

    name: str
    urdf_path: Path
    mass: float  # kg
    inertia: tuple[float, float, float]  # kg m^2, principal moments (x, y, z)
    arm_length: float  # m, centre to rotor axis
    configuration: str  # 'x' or 'plus'
    kf: float  # thrust coefficient, N/(rad/s)^2
    km: float  # drag-torque coefficient, N m/(rad/s)^2
    motor_time_constant: float  # s
    max_rotor_speed: float  # rad/s
    collision_size: tuple[float, float, float]  # m, box extents (x, y, z)
    param_file: Path | None = None  # the YAML these parameters were read from (for error messages)
    rotor_radius: float | None = None  # m (None: 0.6 arm_length, see ``rotor_radius_m``)
    rotor_solidity: float | None = None  # -, blade area over disc area (None: ``DEFAULT_SOLIDITY``)
    drag_xy: float | None = None  # N/(m/s), horizontal rotor drag near hover (None: ``drag_coefficients``)
    drag_z: float | None = None  # N/(m/s), vertical rotor drag near hover

    @property
    def drag_coefficients(self) -> NDArray[np.float64]:
        """(3,) N/(m/s), linear drag near hover along x, y, z: the file's ``drag_xy`` and ``drag_z``, else the
        Crazyflie's (``CF2X_DRAG_PER_WEIGHT``) times this airframe's weight (rotor drag grows with thrust)."""
        xy = self.drag_xy if self.drag_xy is not None else CF2X_DRAG_PER_WEIGHT[0] * self.mass * G0
        z = self.drag_z if self.drag_z is not None else CF2X_DRAG_PER_WEIGHT[1] * self.mass * G0
        return np.array([xy, xy, z], dtype=float)

    @property
    def rotor_radius_m(self) -> float:
        """Rotor radius, m: the file's ``rotor_radius``, else 0.6 arm_length."""
        return float(self.rotor_radius) if self.rotor_radius is not None else 0.6 * self.arm_length

    @property
    def downwash_params(self) -> DownwashParams:
        """Constants of the wake model (``pybullet_swarm.vehicle.downwash``) of this airframe."""
        return DownwashParams(
            rotor_radius=self.rotor_radius_m,
            arm_length=self.arm_length,
            kf=self.kf,
            solidity=DEFAULT_SOLIDITY if self.rotor_solidity is None else float(self.rotor_solidity),
            configuration=self.configuration,
        )

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
        return np.stack(
            [
                np.full(4, self.kf),
                self.kf * xy[:, 1],
                -self.kf * xy[:, 0],
                -self.km * self.spin,
            ]
        )

    @functools.cached_property
    def mixer_inverse(self) -> NDArray[np.float64]:
        """Map [thrust, tau_x, tau_y, tau_z] to squared rotor speeds, (4, 4)."""
        return np.asarray(np.linalg.inv(self.mixer), dtype=np.float64)

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
    except OSError:  # e.g. a name too long for the file system
        pass
    raise ConfigError(
        f"unknown vehicle {str(name_or_path)!r}, expected one of {', '.join(bundled_vehicles())} "
        "or a path to a vehicle .yaml file"
    )


@functools.lru_cache(maxsize=64)
def _load(path: Path, stamp: tuple[int, int] = (0, 0)) -> VehicleParams:
    """Parameters of ``path``; ``stamp`` (modification time, size) makes an edited file read again."""
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise ConfigError("must be a mapping of vehicle parameters", source=path.name)
    data = validate(_VehicleFile, raw, source=path.name)
    urdf = path.parent / data.urdf
    try:
        found = urdf.is_file()
    except (OSError, ValueError):  # a name the file system refuses (too long, a NUL character)
        found = False
    if not found:
        raise ConfigError(
            f"URDF file {data.urdf!r} not found beside the parameter file", source=path.name, field="urdf"
        )
    check_urdf(urdf, source=path.name)
    fields = data.model_dump()
    fields.pop("urdf")
    params = VehicleParams(urdf_path=urdf, param_file=path, **fields)
    return params


def load_vehicle(name_or_path: str | Path) -> VehicleParams:
    """Parameters of a bundled vehicle by name ('quad150', 'cf2x') or of a vehicle YAML file."""
    path = _resolve(name_or_path).resolve()
    try:
        st = path.stat()
        stamp = (st.st_mtime_ns, st.st_size)
    except OSError:
        stamp = (0, 0)
    return _load(path, stamp)
