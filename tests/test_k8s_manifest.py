"""docs/k8s/render-indexed-job.yaml runs valid fogsim command lines: pod i of the Indexed Job
renders ``--shard i/N`` into the shared volume, and the finalize Job finalizes that same dataset.

The commands are read as the pod's shell would run them (``sh -c``, with ``$JOB_COMPLETION_INDEX``
and the container's env substituted) and parsed by fogsim's own argparse parser.
"""
import shlex
from pathlib import Path
from string import Template

import pytest

from fogsim.cli import build_parser
from fogsim.runs import parse_shard

yaml = pytest.importorskip("yaml")  # PyYAML: the 'dev' extra

MANIFEST = Path(__file__).resolve().parents[1] / "docs" / "k8s" / "render-indexed-job.yaml"


def documents() -> dict[str, dict]:
    return {d["metadata"]["name"]: d for d in yaml.safe_load_all(MANIFEST.read_text())}


def fogsim_args(container: dict, index: int | None = None):
    """The fogsim command line the container runs, parsed by fogsim's parser."""
    assert container["command"] == ["sh", "-c"] and len(container["args"]) == 1
    env = {e["name"]: e["value"] for e in container.get("env", [])}
    if index is not None:
        env["JOB_COMPLETION_INDEX"] = str(index)  # what the Job controller sets in pod i
    words = shlex.split(Template(container["args"][0]).substitute(env))
    assert words[:2] == ["exec", "fogsim"], words
    return build_parser().parse_args(words[2:])


def volume_of(job: dict, out: str) -> str:
    """The claim whose mount holds ``out`` (the dataset folder)."""
    spec = job["spec"]["template"]["spec"]
    (container,) = spec["containers"]
    mounts = [m for m in container["volumeMounts"] if Path(out).is_relative_to(m["mountPath"])]
    assert len(mounts) == 1, f"--out {out} is on no mounted volume"
    (volume,) = [v for v in spec["volumes"] if v["name"] == mounts[0]["name"]]
    return volume["persistentVolumeClaim"]["claimName"]


def test_indexed_job_renders_shard_i_of_n_into_the_shared_volume():
    docs = documents()
    job = docs["fogsim-render"]
    spec = job["spec"]
    assert spec["completionMode"] == "Indexed" and spec["completions"] == spec["parallelism"]
    n = spec["completions"]
    assert spec["template"]["spec"]["restartPolicy"] == "Never"
    (container,) = spec["template"]["spec"]["containers"]
    outs = set()
    for i in (0, 1, n - 1):
        args = fogsim_args(container, i)
        assert args.command == "render" and args.shard == f"{i}/{n}" and parse_shard(args.shard) == (i, n)
        assert not args.finalize_only and args.quiet
        outs.add(args.out)
    assert len(outs) == 1  # every pod writes into one dataset
    claim = volume_of(job, outs.pop())
    pvc = docs[claim]
    assert pvc["kind"] == "PersistentVolumeClaim" and "ReadWriteMany" in pvc["spec"]["accessModes"]
    with pytest.raises(KeyError, match="JOB_COMPLETION_INDEX"):  # the shard comes from the pod's index
        fogsim_args(container)


def test_finalize_job_finalizes_the_same_dataset():
    docs = documents()
    render, finalize = docs["fogsim-render"], docs["fogsim-finalize"]
    (rc,) = render["spec"]["template"]["spec"]["containers"]
    (fc,) = finalize["spec"]["template"]["spec"]["containers"]
    shard = fogsim_args(rc, 0)
    final = fogsim_args(fc)
    assert final.command == "render" and final.finalize_only and final.shard is None
    for key in ("preset", "frames", "seed", "out", "resolution", "samples", "levels", "train_fraction"):
        assert getattr(final, key) == getattr(shard, key), key
    assert volume_of(finalize, final.out) == volume_of(render, shard.out)
    assert render["metadata"]["labels"]["fogsim/step"] == "render"
    assert finalize["metadata"]["labels"]["fogsim/step"] == "finalize"
    assert "completionMode" not in finalize["spec"]  # one pod
