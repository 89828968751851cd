"""Draw the wake model against the data it is checked on: ``downwash_validation.png``.

Left: the force on a 34 g Crazyflie straight below another (both at hover thrust) against Shi et al.'s
Neural-Swarm points (ICRA 2020, Fig. 3), with the rotor solidity from 0.08 to 0.2 as a band. Middle: the
centreline velocity over U_H and the half-width over l of cf2x and quad150 against Bauersfeld et al.'s
normalised jet (RA-L 2024). Right: quad150's force on one straight below, this model and the empirical
model it replaces (gym-pybullet-drones' fit capped by a momentum bound, as the project used until then).

    python scripts/downwash_validation.py [--out docs/images/downwash_validation.png]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pybullet_swarm.vehicle import load_vehicle  # noqa: E402
from pybullet_swarm.vehicle.downwash import JET_B, JET_S, JET_START, JET_Z0  # noqa: E402

G = 9.81
NEURAL_SWARM = {0.2: 10.0, 0.3: 8.0, 0.4: 6.0, 0.5: 4.0, 0.7: 0.0}  # gf at m below, read off Fig. 3


def old_model_fraction(dz: np.ndarray) -> np.ndarray:
    """The replaced model's force on a quad150 straight below one at hover, over its weight."""
    r, alpha, zeta, eta, min_w, k, m = 0.03175, 12595.4, 0.16, -0.151, 0.053, 0.5, 0.150
    beta = np.maximum(zeta * dz + eta, min_w)
    fitted = alpha / (m * G) * (r / (4.0 * dz)) ** 2
    bound = k * (1.0 - np.exp(-2.0 * r**2 / beta**2))
    return np.minimum(fitted, bound)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/images/downwash_validation.png"))
    args = ap.parse_args()

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.4))
    cf = load_vehicle("cf2x").downwash_params
    w = 0.034 * G
    dz = np.linspace(0.05, 1.0, 96)
    for sigma, style in ((0.08, ":"), (0.2, ":")):
        band = dataclasses.replace(cf, solidity=sigma)
        f = [band.force_on_vehicle(z, upper_thrust=w, lower_thrust=w) / G * 1e3 for z in dz]
        ax[0].plot(dz, f, "k" + style, lw=1, label=f"solidity {sigma}")
    f = [cf.force_on_vehicle(z, upper_thrust=w, lower_thrust=w) / G * 1e3 for z in dz]
    ax[0].plot(dz, f, "C0", lw=2, label=f"model (solidity {cf.solidity})")
    ax[0].plot(list(NEURAL_SWARM), list(NEURAL_SWARM.values()), "o", color="C3", label="Neural-Swarm, Fig. 3")
    for z, v in NEURAL_SWARM.items():
        ax[0].fill_between([z - 0.01, z + 0.01], v - 2, v + 2, color="C3", alpha=0.15, lw=0)
    ax[0].set(xlabel="vertical distance m", ylabel="force gram-force", title="34 g Crazyflie below another, hover")
    ax[0].legend(fontsize=8)

    for name, colour in (("cf2x", "C0"), ("quad150", "C1")):
        p = load_vehicle(name)
        dw = p.downwash_params
        ell = dw.diagonal
        t = p.mass * G
        zl = np.linspace(0.02, 30.0, 600)
        uc, b = np.array([dw.centreline(z * ell, t) for z in zl]).T
        ax[1].plot(zl, uc / dw.hover_velocity(t), color=colour, lw=2, label=f"{name}: Uc / U_H")
        ax[1].plot(zl, b / ell, color=colour, lw=1, ls="--", label=f"{name}: b / l")
    zl = np.linspace(JET_START, 30.0, 100)
    ax[1].plot(zl, JET_B / (zl - JET_Z0), "k:", lw=1.5, label="jet: B / (z/l - z0/l)")
    ax[1].plot(zl, JET_S * (zl - JET_Z0), "k-.", lw=1, label="jet: S (z/l - z0/l)")
    ax[1].axvline(JET_START, color="0.6", lw=0.8)
    ax[1].set(xlabel="z / l (l: motor-to-motor diagonal)", title="normalised jet (Bauersfeld et al.)")
    ax[1].legend(fontsize=8)

    q = load_vehicle("quad150")
    dq = q.downwash_params
    wq = q.mass * G
    dz = np.linspace(0.02, 3.0, 150)
    new = [dq.force_on_vehicle(z, upper_thrust=wq, lower_thrust=wq) / wq for z in dz]
    ax[2].plot(dz, new, "C0", lw=2, label="this model")
    ax[2].plot(dz, old_model_fraction(dz), "C7", lw=1.5, label="replaced empirical model")
    ax[2].axhline(0.05, color="0.6", lw=0.8, ls="--")
    ax[2].set(xlabel="vertical distance m", ylabel="force / weight", title="quad150 below another, hover")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(args.out)
    for z, v in NEURAL_SWARM.items():
        m = cf.force_on_vehicle(z, upper_thrust=w, lower_thrust=w) / G * 1e3
        print(f"{z:.1f} m: model {m:.2f} gf, Neural-Swarm {v:.0f} gf, residual {m - v:+.2f} gf")
    print(
        "quad150 column at 5 %:",
        dq.column(0.05, mass=q.mass),
        "with a 10 g load:",
        dq.column(0.05, mass=q.mass, load=0.01),
    )


if __name__ == "__main__":
    main()
