"""A Ray cluster on 127.0.0.1 for the tests and the benchmark.

Its nodes (a head and workers, one CPU each by default) run inside a network
and PID namespace of their own (`unshare -n -p -f --mount-proc`, then `ip
link set lo up`; `-r` adds a user namespace when not root): every node
binds 127.0.0.1 of that namespace only, so nothing outside can reach it,
and killing the namespace's first process ends every process Ray started.
Commands join its network namespace with `nsenter` (see `enter`).
"""

from __future__ import annotations

import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HEAD_PORT = 6379
WORKER_PORT = 6390  # the first worker node's raylet (found by it to be killed)
START_S = 90  # a cluster not up by then is an error
LIFETIME_S = 1800  # the namespace ends by itself after this, whatever happens
ADDRESS = f"127.0.0.1:{HEAD_PORT}"


def clean_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k not in ("VIRTUAL_ENV", "PYTHONHOME", "PUPPER_PYTHON", "RAY_ADDRESS")}


class LoopbackCluster:
    """A Ray head and `nodes - 1` worker nodes of `cpus` CPUs each, on
    127.0.0.1 in private namespaces. The first worker node's raylet listens
    on WORKER_PORT (so a test can find and kill it). `env` is added to the
    nodes' environment (their workers inherit it)."""

    def __init__(self, nodes: int = 2, cpus: int = 1, env: dict[str, str] | None = None) -> None:
        self.root = os.geteuid() == 0
        # short: Ray's socket paths under it must fit in 107 bytes
        self.tmp = Path(tempfile.mkdtemp(prefix="pr", dir="/tmp"))
        ray = Path(sys.executable).parent / "ray"
        common = (f"--node-ip-address 127.0.0.1 --num-cpus {cpus} --disable-usage-stats "
                  f"--temp-dir {self.tmp}")
        workers = "\n".join(
            f"{ray} start --address {ADDRESS} --node-manager-port {WORKER_PORT + i} {common} "
            f">>{self.tmp}/start.log 2>&1"
            for i in range(nodes - 1)
        )
        script = f"""
set -e
export PATH="$PATH:/usr/sbin:/sbin"  # ip, where a user's PATH lacks them
ip link set lo up
export RAY_USAGE_STATS_ENABLED=0
{ray} start --head --port {HEAD_PORT} --include-dashboard=false {common} >{self.tmp}/start.log 2>&1
{workers}
echo READY
exec sleep {LIFETIME_S}
"""
        flags = ["-n", "-p", "-f", "--mount-proc"] + ([] if self.root else ["-r"])
        self.proc = subprocess.Popen(
            ["unshare", *flags, "bash", "-c", script],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env={**clean_env(), **(env or {})}, start_new_session=True,
        )
        deadline = time.monotonic() + START_S
        line = ""
        while time.monotonic() < deadline and self.proc.poll() is None:
            ready, _, _ = select.select([self.proc.stdout], [], [], 1.0)
            if ready:
                line = self.proc.stdout.readline()
                if line.strip() == "READY":
                    break
        if line.strip() != "READY":
            log = (self.tmp / "start.log").read_text() if (self.tmp / "start.log").exists() else ""
            self.stop()
            raise RuntimeError(f"the loopback Ray cluster did not start in {START_S} s:\n{line}\n{log}")
        # the namespace's first process (sleep, once the script exec'd it)
        children = Path(f"/proc/{self.proc.pid}/task/{self.proc.pid}/children").read_text()
        self.init_pid = int(children.split()[0])

    def enter(self, *, pids: bool = False) -> list[str]:
        """nsenter's arguments to run a command in the cluster's network
        namespace (and, with `pids`, its PID and mount namespaces)."""
        ns = ["-n"] + (["-p", "-m"] if pids else [])
        user = [] if self.root else ["-U", "--preserve-credentials"]
        return ["nsenter", "-t", str(self.init_pid), *user, *ns, "--"]

    def kill_worker_node(self) -> None:
        """SIGKILLs the second node's raylet (its workers die with it)."""
        subprocess.run([*self.enter(pids=True), "pkill", "-9", "-f",
                        f"raylet.*node_manager_port={WORKER_PORT}"], check=True, timeout=30)

    def stop(self) -> None:
        # the namespace's first process ends, and with it all Ray started
        try:
            os.kill(getattr(self, "init_pid", self.proc.pid), signal.SIGKILL)
        except ProcessLookupError:
            pass
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait(timeout=30)
        shutil.rmtree(self.tmp, ignore_errors=True)
