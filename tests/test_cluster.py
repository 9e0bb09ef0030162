"""The cluster path, run for real: a single-node Slurm started by the test, array jobs of
``fogsim render --shard`` and ``fogsim fog --shard``, then ``--finalize-only`` as a dependent
job — and each dataset equals a one-process run of the same seed, byte for byte.

Slurm here is Debian's ``slurm-wlm`` 22.05 with ``munge`` (``.ci/run`` installs them): munged,
slurmctld and slurmd run as root from a generated ``slurm.conf`` in a temporary folder
(proctrack/linuxproc, task/none: no cgroups needed), on free local ports, and are stopped at the
end (jobs cancelled first). Where the packages are missing, this is not root, or the daemons do
not come up, the test skips and says why. Every wait is bounded: ``sbatch --wait`` under a
subprocess timeout, the finalize job cancelled if its dependency fails, the start-up poll
limited.

What is compared, byte for byte: images, labels, depth, masks, COCO files, ``dataset.json``,
``render_run.json`` / ``fogsim_run.json``, the contact sheet. Two kinds of file differ by
design and are compared after normalising: ``meta/<frame>.json`` of a render holds the frame's
timings (``timings_s``, wall-clock seconds), and ``splits/*.txt`` and ``data/*.yaml`` hold the
dataset's absolute path (Ultralytics needs it), which is another folder for each run.
"""
from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.slow, pytest.mark.blender]

RENDER = ["--frames", "4", "--resolution", "96x64", "--samples", "2", "--levels", "clear,0.06", "--seed", "3"]
FOG = ["--levels", "clear,0.06", "--seed", "2"]
JOB_TIMEOUT_S = 900  # the longest a group of jobs may take before the test gives up (and cancels them)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Slurm:
    """munged + slurmctld + slurmd on this host, from files in ``folder``; :meth:`stop` ends them."""

    def __init__(self, folder: Path):
        self.dir, self.procs = folder, []
        self.env = dict(os.environ, SLURM_CONF=str(folder / "slurm.conf"))

    def start(self) -> None:
        d = self.dir
        for sub in ("munge", "state", "spool", "log"):
            (d / sub).mkdir(mode=0o700)
        subprocess.run(["mungekey", "--create", f"--keyfile={d / 'munge' / 'munge.key'}"], check=True,
                       capture_output=True, timeout=60)
        socket_path = d / "munge" / "munge.socket"
        self._spawn("munged", ["munged", "-F", "--force", f"--socket={socket_path}",
                               f"--key-file={d / 'munge' / 'munge.key'}", f"--log-file={d / 'log' / 'munged.log'}",
                               f"--pid-file={d / 'munge' / 'munged.pid'}", f"--seed-file={d / 'munge' / 'seed'}"])
        self._wait(lambda: socket_path.exists(), "munged did not create its socket")
        node = socket.gethostname().split(".")[0]
        (d / "slurm.conf").write_text("\n".join([
            "ClusterName=fogsimtest", f"SlurmctldHost={node}(127.0.0.1)", "SlurmUser=root", "SlurmdUser=root",
            f"SlurmctldPort={_free_port()}", f"SlurmdPort={_free_port()}",
            "AuthType=auth/munge", f"AuthInfo=socket={socket_path}", "CredType=cred/munge",
            f"StateSaveLocation={d / 'state'}", f"SlurmdSpoolDir={d / 'spool'}",
            f"SlurmctldPidFile={d / 'slurmctld.pid'}", f"SlurmdPidFile={d / 'slurmd.pid'}",
            f"SlurmctldLogFile={d / 'log' / 'slurmctld.log'}", f"SlurmdLogFile={d / 'log' / 'slurmd.log'}",
            "ProctrackType=proctrack/linuxproc", "TaskPlugin=task/none", "JobAcctGatherType=jobacct_gather/none",
            "AccountingStorageType=accounting_storage/none", "SelectType=select/cons_tres",
            "SelectTypeParameters=CR_CPU", "MpiDefault=none", "ReturnToService=2", "MailProg=/bin/true",
            f"NodeName={node} NodeAddr=127.0.0.1 CPUs={os.cpu_count() or 1} State=UNKNOWN",
            "PartitionName=debug Nodes=ALL Default=YES MaxTime=60 State=UP", ""]))
        self._spawn("slurmctld", ["slurmctld", "-D", "-i"])
        self._spawn("slurmd", ["slurmd", "-D"])
        self._wait(self._idle, "the node did not become idle")

    def _spawn(self, name: str, cmd: list[str]) -> None:
        log = open(self.dir / "log" / f"{name}.out", "wb")
        self.procs.append((name, subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT)))

    def _idle(self) -> bool:
        res = self.run(["sinfo", "-h", "-o", "%t"], timeout=10)
        return res.returncode == 0 and res.stdout.strip() == "idle"

    def _wait(self, ready, what: str, seconds: float = 600) -> None:
        """Wait until ``ready()``: returns as soon as it is; ``seconds`` only bounds a hang (daemons
        start slowly on a loaded machine — a test must not depend on its speed)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            dead = [name for name, p in self.procs if p.poll() is not None]
            if dead:
                raise RuntimeError(f"{', '.join(dead)} exited: {self.logs()}")
            try:
                if ready():
                    return
            except subprocess.TimeoutExpired:
                pass
            time.sleep(0.5)
        raise RuntimeError(f"{what} within {seconds:.0f} s: {self.logs()}")

    def logs(self) -> str:
        return " | ".join(f"{p.name}: {p.read_text(errors='replace')[-600:]}"
                          for p in sorted((self.dir / "log").glob("*")) if p.is_file())

    def run(self, cmd: list[str], timeout: float = 60) -> subprocess.CompletedProcess:
        return subprocess.run(cmd, env=self.env, capture_output=True, text=True, timeout=timeout, cwd=self.dir)

    def sbatch(self, *args: str, wait: bool = False) -> str:
        """Submit; returns the job id. With ``wait``, until the job ends (bounded); a failed job fails the test."""
        cmd = ["sbatch", "--parsable", "--time=30", "--kill-on-invalid-dep=yes", *(["--wait"] if wait else []),
               *args]
        try:
            res = self.run(cmd, timeout=JOB_TIMEOUT_S if wait else 60)
        except subprocess.TimeoutExpired:
            self.run(["scancel", "--user=root"])
            pytest.fail(f"sbatch {' '.join(args[:3])} … did not finish within {JOB_TIMEOUT_S} s: {self.logs()}")
        assert res.returncode == 0, f"sbatch {args}: exit {res.returncode}: {res.stdout} {res.stderr}"
        return res.stdout.strip().split(";")[0].splitlines()[0]

    def stop(self) -> None:
        try:
            self.run(["scancel", "--user=root"], timeout=30)
        except (subprocess.TimeoutExpired, OSError):
            pass
        for _, p in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait(timeout=20)


@pytest.fixture(scope="module")
def slurm():
    missing = [b for b in ("munged", "mungekey", "slurmctld", "slurmd", "sbatch", "sinfo", "scancel")
               if shutil.which(b) is None]
    if missing:
        pytest.skip(f"Slurm is not installed (missing {', '.join(missing)}: apt-get install slurm-wlm munge)")
    if os.geteuid() != 0:
        pytest.skip("starting munged, slurmctld and slurmd with a generated slurm.conf needs root")
    import importlib.util

    if importlib.util.find_spec("bpy") is None:
        pytest.skip("the bpy module is not installed (the 'blender' extra): nothing to render on the cluster")
    folder = Path(tempfile.mkdtemp(prefix="fogsim_slurm_"))  # short: munge's socket path has a length limit
    os.chmod(folder, 0o700)
    cluster = Slurm(folder)
    try:
        try:
            cluster.start()
        except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
            pytest.skip(f"Slurm could not start here: {exc}")
        yield cluster
    finally:
        cluster.stop()
        shutil.rmtree(folder, ignore_errors=True)


def fogsim_cmd(*args) -> str:
    """A job's command line: this checkout's fogsim with this interpreter."""
    return " ".join([f"PYTHONPATH={ROOT}", "exec", sys.executable, "-m", "fogsim", *map(str, args)])


def run_here(*args) -> None:
    res = subprocess.run([sys.executable, "-m", "fogsim", *map(str, args)], cwd=ROOT, capture_output=True,
                         text=True, timeout=JOB_TIMEOUT_S)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]


def dataset_files(root: Path) -> dict[str, bytes]:
    """Every file by relative path; the two by-design differences normalised (see the module doc)."""
    files = {}
    for p in sorted(root.rglob("*")):
        if not p.is_file():
            continue
        rel = p.relative_to(root).as_posix()
        data = p.read_bytes()
        if rel.startswith(("splits/", "data/")):
            data = data.replace(str(root).encode(), b"<OUT>")
        elif rel.startswith("meta/") and b'"timings_s"' in data:
            meta = json.loads(data)
            meta.pop("timings_s")
            data = json.dumps(meta, sort_keys=True).encode()
        files[rel] = data
    return files


def assert_same_dataset(array: Path, one: Path, kinds: tuple[str, ...]) -> None:
    a, b = dataset_files(array), dataset_files(one)
    assert sorted(a) == sorted(b)
    differ = [rel for rel in a if a[rel] != b[rel]]
    assert differ == [], f"differ from the one-process run: {differ}"
    for kind in kinds:
        assert any(rel.startswith(kind + "/") for rel in a), f"no {kind}/ files"


def job_logs(folder: Path, pattern: str) -> list[list[str]]:
    return [[ln for ln in p.read_text().splitlines() if ln.strip()] for p in sorted(folder.glob(pattern))]


def test_slurm_array_render_and_fog_equal_one_process_runs(slurm, tmp_path):
    t0 = time.monotonic()
    logs = tmp_path / "logs"
    logs.mkdir()
    # --- render: an array of 2 shards, then --finalize-only once both succeeded
    out = tmp_path / "render_array"
    array = slurm.sbatch("--array=0-1", "--job-name=render", f"--output={logs}/render_%a.out", f"--chdir={ROOT}",
                         "--wrap", fogsim_cmd("render", "--out", out, *RENDER,
                                              "--shard", "$SLURM_ARRAY_TASK_ID/2", "--quiet"))
    slurm.sbatch(f"--dependency=afterok:{array}", "--job-name=render_finalize", f"--output={logs}/render_fin.out",
                 f"--chdir={ROOT}", "--wrap", fogsim_cmd("render", "--out", out, *RENDER, "--finalize-only",
                                                         "--quiet"), wait=True)
    shards = job_logs(logs, "render_[01].out")
    assert len(shards) == 2 and all(len(s) == 1 and s[0].startswith("rendered 2 frames") for s in shards), shards
    assert not (tmp_path / "render_array" / ".fogsim_tmp").exists()
    run_here("render", "--out", tmp_path / "render_one", *RENDER, "--quiet")
    assert_same_dataset(out, tmp_path / "render_one", ("images", "labels", "depth", "masks", "meta", "coco"))
    # --- fog: a labelled Cityscapes tree, 2 shards, then --finalize-only
    from cityscapes_tree import make_tree

    cs = make_tree(tmp_path / "cityscapes")
    fog_out = tmp_path / "fog_array"
    array = slurm.sbatch("--array=0-1", "--job-name=fog", f"--output={logs}/fog_%a.out", f"--chdir={ROOT}",
                         "--wrap", fogsim_cmd("fog", "--cityscapes", cs, "--out", fog_out, *FOG,
                                              "--shard", "$SLURM_ARRAY_TASK_ID/2", "--quiet"))
    slurm.sbatch(f"--dependency=afterok:{array}", "--job-name=fog_finalize", f"--output={logs}/fog_fin.out",
                 f"--chdir={ROOT}", "--wrap", fogsim_cmd("fog", "--finalize-only", "--out", fog_out, "--quiet"),
                 wait=True)
    assert [s[0].split(" in ")[0] for s in job_logs(logs, "fog_[01].out")] == \
        ["fogged 1 of 1 images × 2 levels (0 already done, 0 failed)"] * 2
    assert job_logs(logs, "fog_fin.out")[0][0].startswith("dataset: 2 frames")
    run_here("fog", "--cityscapes", cs, "--out", tmp_path / "fog_one", *FOG, "--quiet")
    assert_same_dataset(fog_out, tmp_path / "fog_one", ("images", "labels", "meta", "coco"))
    print(f"slurm test: {time.monotonic() - t0:.0f} s after the cluster started")
