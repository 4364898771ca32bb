"""The Ray side of ``--ray``.

The driver (:class:`Driver`, used by the Rust core through the bridge)
connects to a cluster, puts the sweep's shared inputs in Ray's object store
once, and runs tasks of cells there; a task (:func:`run_task`) runs on any
node where ``pupper_core`` is importable and hands back its cells' results,
encoded. What goes into a task, and what is written when, is decided in
Rust (``pupper_core::cluster``); this module only talks to Ray.
"""

from __future__ import annotations

import json
import logging
import os
import socket
import sys
from typing import Any

#: Ray runs a task again this often when the worker or node running it dies.
RETRIES = 3

_FIX_RAY = (
    "install the optional extra: pip install 'pupper_core[ray]' "
    "(in a checkout: make setup PUPPER_EXTRAS=ray)"
)


class RayUnavailable(Exception):
    """Ray is not installed here."""


class ClusterUnreachable(Exception):
    """No cluster at the address, or one that cannot run a task."""


class ClusterFailure(Exception):
    """A task failed for good (its retries spent), or a node cannot run pupper."""


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise RayUnavailable(
            f"--ray needs Ray, but the Python package 'ray' is not installed in "
            f"{sys.executable}: {_FIX_RAY}"
        ) from None
    return ray


def version() -> str | None:
    """Ray's version, or None when it is not installed."""
    try:
        import ray
    except ImportError:
        return None
    return str(ray.__version__)


def _last_line(e: BaseException) -> str:
    """A traceback's last line: what happened."""
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    return (lines[-1] if lines else type(e).__name__)[:300]


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__


def _host_port(address: str) -> tuple[str, str]:
    if address == "auto":
        address = os.environ.get("RAY_ADDRESS", "")
    host, _, port = address.removeprefix("ray://").rpartition(":")
    return host.strip("[]"), port


#: The HTTP/2 client preface and an empty SETTINGS frame: what a gRPC
#: client sends first. Ray's head (its GCS) and its client server are gRPC
#: servers, which answer with a SETTINGS frame of their own.
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"
#: Seconds the probe waits for an answer.
PROBE_SECONDS = 5.0


def _probe(address: str) -> None:
    """Fails at once when nothing listens at the address, or when what
    listens is not a gRPC server (a web server, say): Ray itself keeps
    retrying either for minutes."""
    host, port = _host_port(address)
    if not host or not port.isdigit():
        return  # auto without RAY_ADDRESS: Ray looks for a local cluster itself
    try:
        with socket.create_connection((host, int(port)), timeout=PROBE_SECONDS) as s:
            s.settimeout(PROBE_SECONDS)
            s.sendall(_H2_PREFACE)
            reply = b""
            while len(reply) < 9:
                chunk = s.recv(9 - len(reply))
                if not chunk:
                    break
                reply += chunk
    except socket.timeout:
        reply = b""
    except OSError as e:
        raise ClusterUnreachable(
            f"nothing answers at {address} ({e.strerror or _one_line(e)}): start the "
            f"cluster's head there (ray start --head --port {port}), or check the address"
        ) from None
    # a frame header: 3 bytes of length, then the type; 0x04 is SETTINGS
    if len(reply) < 9 or reply[3] != 0x04:
        said = reply.split(b"\r\n", 1)[0].decode("latin-1").strip()
        what = f"it answered {said[:60]!r}" if said else "it answered nothing a Ray head would"
        raise ClusterUnreachable(
            f"{address} is not a Ray cluster ({what}): give the head's address "
            f"(`ray start --head` prints it; its port is 6379 unless set, 10001 for ray://)"
        ) from None


def versions() -> tuple[str, str]:
    """pupper_core's and mujoco's versions here (a worker's, in `Driver`'s
    check)."""
    import mujoco

    from pupper_core import _native

    return str(_native.__version__), str(mujoco.__version__)


def run_task(job: bytes, task: bytes) -> bytes:
    """A task on a worker: the task's cells of the job, through this node's
    CPUs that Ray gave the task, as one batch."""
    import ray

    from pupper_core import _native

    cpus = ray.get_runtime_context().get_assigned_resources().get("CPU", 1.0)
    return bytes(_native._run_task(job, task, max(1, int(cpus))))


class Driver:
    """A connection to a Ray cluster running one job's tasks."""

    def __init__(self, address: str, job: bytes, threads: int, gpus: float) -> None:
        ray = _ray()
        self._ray = ray
        self._pending: dict[Any, int] = {}
        self._failure: Exception | None = None
        # a notebook that connected itself keeps its connection
        self._owns = not ray.is_initialized()
        if not self._owns and address != "auto":
            raise ClusterUnreachable(
                f"this Python is already connected to a Ray cluster, so ray={address!r} "
                "cannot be reached from it: pass ray='auto' to run on that connection, "
                "or call ray.shutdown() first"
            )
        try:
            self._start(address, job, threads, gpus)
        except BaseException:
            self.close()
            raise

    def _start(self, address: str, job: bytes, threads: int, gpus: float) -> None:
        ray = self._ray
        if self._owns:
            _probe(address)
            extra: dict[str, Any] = {}
            text = os.environ.get("RAY_RUNTIME_ENV")
            if text and not address.startswith("ray://"):  # Ray's client reads it itself
                # what the tasks' workers get: e.g. a conda env with pupper_core
                try:
                    extra["runtime_env"] = json.loads(text)
                except ValueError as e:
                    raise ClusterFailure(
                        f"RAY_RUNTIME_ENV is not JSON ({e}): give a runtime_env as JSON, "
                        """e.g. '{"conda": "pupper"}'"""
                    ) from None
            self._connect(address, extra)
        self._nodes = [n for n in ray.nodes() if n.get("Alive")]
        cpus = [float(n.get("Resources", {}).get("CPU", 0.0)) for n in self._nodes]
        most = int(max(cpus, default=0.0))
        if most < 1:
            raise ClusterUnreachable(
                f"the Ray cluster at {address!r} has no node with a CPU: "
                "start its nodes with --num-cpus 1 or more"
            )
        if gpus > 0:
            # one GPU per task, and one CPU to drive it
            per = 1
            slots = int(sum(float(n.get("Resources", {}).get("GPU", 0.0)) for n in self._nodes) // gpus)
            if slots < 1:
                raise ClusterUnreachable(
                    f"--backend warp on a CUDA device asks each task for a GPU, but the Ray "
                    f"cluster at {address!r} has none: use --device cpu, or add GPU nodes"
                )
        else:
            # a task takes a node's cores: as many as the smallest node has
            per = threads if threads > 0 else int(min(c for c in cpus if c >= 1))
            if per > most:
                raise ClusterUnreachable(
                    f"--threads {threads} asks each task for more CPUs than any node of the "
                    f"Ray cluster has (at most {most}): give --threads {most} or fewer, "
                    "or 0 for the smallest node's"
                )
            slots = sum(int(c // per) for c in cpus)
        self._per = per
        self._slots = max(1, slots)
        self._check()
        self._job = ray.put(job)
        self._remote = ray.remote(run_task).options(
            num_cpus=per, num_gpus=gpus, max_retries=RETRIES
        )

    def _connect(self, address: str, extra: dict[str, Any]) -> None:
        ray = self._ray
        for attempt in (1, 2):
            try:
                ray.init(
                    address=address,
                    logging_level=logging.WARNING,
                    log_to_driver=False,
                    **extra,
                )
                return
            except Exception as e:  # Ray raises ConnectionError, ValueError, RuntimeError...
                ray.shutdown()
                # the head's client server starts a process per connection,
                # which has been seen failing once on a fresh node: try again
                if attempt == 1 and "Ray client server failed" in str(e):
                    continue
                raise ClusterUnreachable(
                    f"cannot connect to the Ray cluster at {address!r} ({_one_line(e)}): "
                    "start one with `ray start --head` (see README), or check the address "
                    "(auto reads RAY_ADDRESS)"
                ) from None

    def _check(self) -> None:
        """A worker must import pupper_core and mujoco of the driver's
        versions: checked once on one worker before anything is written
        (every task checks its own node again)."""
        ray = self._ray
        try:
            theirs = ray.get(ray.remote(versions).options(num_cpus=0).remote(), timeout=300)
        except ray.exceptions.RayError as e:
            if "No module named" in str(e):
                raise ClusterFailure(
                    "a Ray worker cannot import pupper_core and mujoco: install them on every "
                    "node, into the Python that runs `ray start` (pip install the wheel "
                    "`make wheel` writes to dist/; see README)"
                ) from None
            raise ClusterFailure(
                f"no Ray worker could start a first task ({type(e).__name__}: "
                f"{_last_line(e)}): check the cluster (`ray status`)"
            ) from None
        if tuple(theirs) != versions():
            raise ClusterFailure(
                f"a Ray worker has pupper_core {theirs[0]} and mujoco {theirs[1]}, this driver "
                f"{versions()[0]} and {versions()[1]}: install the same on every node (the "
                "wheel `make wheel` writes to dist/)"
            )

    def capacity(self) -> tuple[int, int]:
        """Tasks that run at once, and CPUs (threads) per task."""
        return self._slots, self._per

    def nodes(self) -> list[tuple[str, str, float]]:
        """(host name, address, CPUs) of each live node."""
        return [
            (
                str(n.get("NodeManagerHostname", "")),
                str(n.get("NodeManagerAddress", "")),
                float(n.get("Resources", {}).get("CPU", 0.0)),
            )
            for n in self._nodes
        ]

    def submit(self, key: int, task: bytes) -> None:
        self._pending[self._remote.remote(self._job, task)] = key

    def wait(self, timeout: float) -> list[tuple[int, bytes]]:
        """Tasks finished within `timeout` seconds (at least one, unless
        none finished): (key, encoded outcome)."""
        if self._failure is not None:
            failure, self._failure = self._failure, None
            raise failure
        if not self._pending:
            return []
        ray = self._ray
        refs = list(self._pending)
        ready, _ = ray.wait(refs, num_returns=1, timeout=timeout)
        if ready:
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
        out: list[tuple[int, bytes]] = []
        for ref in ready:
            key = self._pending.pop(ref)
            try:
                out.append((key, self._get(ref)))
            except Exception as e:
                # the tasks finished beside a failed one are handed over first
                self._failure = self._failure or e
        if not out and self._failure is not None:
            failure, self._failure = self._failure, None
            raise failure
        return out

    def _get(self, ref: Any) -> bytes:
        ray = self._ray
        try:
            return bytes(ray.get(ref))
        except ray.exceptions.RayError as e:
            last = _last_line(e)
            if type(getattr(e, "cause", None)).__name__ == "PanicException":
                # a bug in pupper on the worker: not the user's to fix
                raise RuntimeError(f"a pupper task panicked on the Ray cluster: {last}") from None
            if "No module named 'pupper_core'" in str(e):
                raise ClusterFailure(
                    "a Ray worker cannot import pupper_core: install it on every node, into "
                    "the Python that runs `ray start` (pip install the wheel `make wheel` "
                    "writes to dist/; see README)"
                ) from None
            if isinstance(e, ray.exceptions.RayTaskError):
                raise ClusterFailure(
                    f"a task failed on the Ray cluster ({last}); finished cells are kept: "
                    "continue with --resume"
                ) from None
            raise ClusterFailure(
                f"a task of cells failed {RETRIES + 1} times on the Ray cluster "
                f"({type(e).__name__}: {last}); finished cells are kept: check the cluster "
                "(`ray status`), then continue with --resume"
            ) from None

    def cancel(self) -> None:
        for ref in self._pending:
            try:
                self._ray.cancel(ref, force=True)
            except Exception:  # already finished or gone: nothing to stop
                pass
        self._pending.clear()

    def close(self) -> None:
        self._pending.clear()
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
