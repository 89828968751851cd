"""A sweep on a Ray cluster started with ``ray start``: a head node and a worker node on this machine,
joined by address, one CPU each; the sweep is given the head's address (``--executor ray --address``).

The nodes run ``ray start --block`` in their own sessions, and the fixture stops exactly them (their
process groups, then any process left that runs from the cluster's own temporary directory): other
Ray instances on the machine are left alone, which ``ray stop`` would not do.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Iterator

import pytest

pytestmark = pytest.mark.ray

#: hover shortened to ~1 s simulated (as tests/experiment/test_sweep.py's HOVER)
HOVER = [
    "task.time_limit_s=3.0",
    "task.relative=false",
    "task.waypoints=[{t_s: 0.0, position: [1.5, 1.5, 0.3]}]",
    "task.hold_s=0.2",
    "task.tolerance_m=0.1",
    "agents.start_jitter=0.05",
]


#: a driver that waits (45 s at most) until the cluster at argv[1] has two live nodes with a CPU each
WAIT_FOR_NODES = """
import sys, time
import ray
ray.init(address=sys.argv[1], log_to_driver=False, logging_level="ERROR")
deadline = time.monotonic() + 45.0
while ray.cluster_resources().get("CPU", 0) < 2 or len([n for n in ray.nodes() if n["Alive"]]) < 2:
    if time.monotonic() > deadline:
        sys.exit(f"cluster resources: {ray.cluster_resources()}")
    time.sleep(0.5)
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ray_cli() -> str:
    exe = Path(sys.executable).with_name("ray")
    found = str(exe) if exe.is_file() else shutil.which("ray")
    if found is None:
        pytest.skip("the ray command is not installed")
    return found


def _start_node(cli: str, temp: str, log: Path, *args: str) -> subprocess.Popen[bytes]:
    """``ray start --block`` for one node of one CPU, in a session of its own (stopped as a group)."""
    cmd = [
        cli,
        "start",
        "--block",
        "--num-cpus=1",
        "--disable-usage-stats",
        f"--temp-dir={temp}",
        f"--dashboard-agent-listen-port={_free_port()}",
        f"--dashboard-agent-grpc-port={_free_port()}",
        f"--metrics-export-port={_free_port()}",
        *args,
    ]
    with open(log, "wb") as fh:
        return subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)


def _stop(procs: list[subprocess.Popen[bytes]], temp: str, grace_s: float = 8.0) -> None:
    """Stop the nodes' process groups (SIGTERM, SIGKILL after ``grace_s``), then kill whatever still
    runs from the cluster's temporary directory."""
    for p in procs:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    for p in procs:
        try:
            p.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=10)
    for pid in _pids_running_from(temp):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, signal.SIGKILL)


def _pids_running_from(temp: str) -> list[int]:
    """Processes whose command line names the cluster's temporary directory (Linux: /proc)."""
    pids = []
    for entry in Path("/proc").glob("[0-9]*"):
        with contextlib.suppress(OSError):
            if temp.encode() in (entry / "cmdline").read_bytes():
                pids.append(int(entry.name))
    return pids


@pytest.fixture
def ray_cluster(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """A head node and one worker node joined to it; yields the head's address."""
    pytest.importorskip("ray")
    if not Path("/proc/self/cmdline").is_file():
        pytest.skip("stopping the cluster's processes needs Linux's /proc")
    cli = _ray_cli()
    # a private cluster of this test: without token authentication (a head started where a token
    # file exists would turn it on, and a joining node would not have it), in the nodes and the drivers
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    temp = tempfile.mkdtemp(prefix="rs-", dir="/tmp")  # short: Ray's socket paths live under it
    port = _free_port()
    address = f"127.0.0.1:{port}"
    procs: list[subprocess.Popen[bytes]] = []
    try:
        head_args = ("--head", f"--port={port}", "--include-dashboard=false")
        procs.append(
            _start_node(cli, temp, tmp_path / "head.log", *head_args, f"--ray-client-server-port={_free_port()}")
        )
        procs.append(_start_node(cli, temp, tmp_path / "worker.log", f"--address={address}"))
        # wait for both nodes, from a process of its own (as every Ray driver below: this process keeps no Ray state)
        wait = subprocess.run(
            [sys.executable, "-c", WAIT_FOR_NODES, address],
            capture_output=True,
            text=True,
            timeout=90,
        )
        if wait.returncode != 0:
            logs = "\n".join((tmp_path / f).read_text(errors="replace")[-1500:] for f in ("head.log", "worker.log"))
            pytest.fail(f"the two Ray nodes did not join ({wait.stdout.strip()} {wait.stderr[-500:]}):\n{logs}")
        yield address
    finally:
        _stop(procs, temp)
        shutil.rmtree(temp, ignore_errors=True)


def test_a_sweep_runs_on_a_two_node_ray_cluster(ray_cluster: str, tmp_path: Path) -> None:
    out = tmp_path / "sw"
    args = ["sweep", "hover", "--seeds", "2", "--grid", "limits.velocity=0.5,1.0"]
    for o in HOVER:
        args += ["--set", o]
    args += ["--executor", "ray", "--address", ray_cluster, "--out", str(out), "--no-plots", "--quiet"]
    # the command a user runs on a machine of the cluster, in a process of its own
    done = subprocess.run(
        [sys.executable, "-m", "pybullet_swarm.cli.main", *args], capture_output=True, text=True, timeout=120
    )
    rows: list[dict[str, Any]] = []
    if (out / "runs.csv").is_file():
        with open(out / "runs.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
    assert done.returncode == 0, (done.stderr[-1000:], [r["error"] for r in rows])
    assert len(rows) == 4 and len({r["run_id"] for r in rows}) == 4
    assert all(r["exit_status"] == "completed" for r in rows), [r["error"] for r in rows]
    for r in rows:  # each row holds its own run's metrics, written by a worker of the cluster
        metrics = json.loads((out / r["run_dir"] / "metrics.json").read_text())
        assert float(r["sim_time_s"]) == metrics["sim_time_s"] and int(r["seed"]) == metrics["seed"]
    assert sorted((r["limits.velocity"], r["seed"]) for r in rows) == [
        ("0.5", "0"),
        ("0.5", "1"),
        ("1.0", "0"),
        ("1.0", "1"),
    ]
