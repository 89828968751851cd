"""Plot a controller design: open-loop Bode diagrams and closed-loop step responses of all loops."""

from __future__ import annotations

from pathlib import Path

import control
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pybullet_swarm.control.design import ControllerDesign, Loop

_BODE_FILE = "bode.png"
_STEP_FILE = "step_response.png"
_DPI = 120
#: Step responses run for this many time constants 1/w_n of the slowest loop of a group.
_STEP_DURATION_WN = 25.0
#: Line style per loop; loops with identical designs (roll, pitch, yaw) stay visible on top of each other.
_LINESTYLE = {Loop.ROLL: "-", Loop.PITCH: "--", Loop.YAW: ":", Loop.X: "-", Loop.Y: "--", Loop.Z: ":"}


def plot_design(design: ControllerDesign, out_dir: Path) -> list[Path]:
    """Write ``bode.png`` and ``step_response.png`` of a design into ``out_dir``; return their paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / _BODE_FILE, out_dir / _STEP_FILE]
    _bode_figure(design).savefig(paths[0], dpi=_DPI)
    _step_figure(design).savefig(paths[1], dpi=_DPI)
    return paths


def _frequency_grid(design: ControllerDesign, loop: Loop) -> NDArray[np.float64]:
    """Frequencies, (n,) rad/s, from well below the slowest loop up to this loop's Nyquist frequency."""
    wn = np.array(list(design.natural_frequency.values()))
    nyquist = np.pi / design.report(loop).sample_period_s * (1.0 - 1e-9)
    return np.logspace(np.log10(wn.min() / 20.0), np.log10(min(wn.max() * 200.0, nyquist)), 800)


def _margin_label(design: ControllerDesign, loop: Loop) -> str:
    rep = design.report(loop)
    gm = "inf" if rep.gain_margin_db is None else f"{rep.gain_margin_db:.1f}"
    return f"{loop.value}: GM {gm} dB, PM {rep.phase_margin_deg:.1f} deg"


def _bode_figure(design: ControllerDesign) -> Figure:
    """Open-loop Bode magnitude and phase of the six loops, margins in the legend."""
    fig = Figure(figsize=(9.0, 7.0), layout="constrained")
    ax_mag, ax_phase = fig.subplots(2, 1, sharex=True)
    for loop in Loop:
        omega = _frequency_grid(design, loop)
        resp = control.frequency_response(design.open_loop(loop), omega)
        mag_db = 20.0 * np.log10(np.abs(np.squeeze(resp.magnitude)))  # (n,) dB
        phase_deg = np.degrees(np.unwrap(np.squeeze(resp.phase)))  # (n,) deg
        # Bring the low-frequency phase of the type-3 loop into (-360, 0] so curves overlay.
        phase_deg -= 360.0 * np.ceil(phase_deg[0] / 360.0)
        color = "tab:blue" if loop.is_attitude else "tab:red"
        style = {"color": color, "linestyle": _LINESTYLE[loop], "alpha": 0.8}
        ax_mag.semilogx(omega, mag_db, label=_margin_label(design, loop), **style)
        ax_phase.semilogx(omega, phase_deg, **style)
    ax_mag.axhline(0.0, color="k", lw=0.8)
    ax_phase.axhline(-180.0, color="k", lw=0.8)
    ax_mag.set_ylabel("|L(exp(jwT))| [dB]")
    ax_mag.set_ylim(-80.0, 80.0)
    ax_phase.set_ylabel("arg L(exp(jwT)) [deg]")
    ax_phase.set_xlabel("frequency [rad/s]")
    ax_mag.set_title(
        f"{design.vehicle}: sampled-data open loops L = C P up to each loop's Nyquist frequency "
        "(blue attitude, red position)"
    )
    ax_mag.legend(fontsize="small", loc="lower left")
    for ax in (ax_mag, ax_phase):
        ax.grid(True, which="both", alpha=0.3)
    return fig


def _step_axes(design: ControllerDesign, ax: Axes, loops: tuple[Loop, ...], unit: str) -> None:
    wn = min(design.natural_frequency[loop.value] for loop in loops)
    for loop in loops:
        dt = design.report(loop).sample_period_s
        t = np.arange(int(np.ceil(_STEP_DURATION_WN / wn / dt)) + 1) * dt  # (n,) s, the loop's samples
        resp = control.step_response(design.closed_loop(loop), T=t)
        bw = design.report(loop).bandwidth_rad_s
        ax.step(
            resp.time,
            np.squeeze(resp.outputs),
            where="post",
            linestyle=_LINESTYLE[loop],
            label=f"{loop.value} (BW {bw:.2f} rad/s)",
        )
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylabel(f"output [{unit}] for a unit step")
    ax.set_xlabel("time [s]")
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)


def _step_figure(design: ControllerDesign) -> Figure:
    """Closed-loop unit step responses (reference to output) of the attitude and position loops."""
    fig = Figure(figsize=(9.0, 7.0), layout="constrained")
    ax_att, ax_pos = fig.subplots(2, 1)
    _step_axes(design, ax_att, (Loop.ROLL, Loop.PITCH, Loop.YAW), "rad")
    _step_axes(design, ax_pos, (Loop.X, Loop.Y, Loop.Z), "m")
    ax_att.set_title(
        f"{design.vehicle}: closed-loop steps (derivative on measurement), separation {design.separation:.2f}"
    )
    return fig
