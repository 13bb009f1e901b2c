"""The cluster examples of docs/campaigns.md (examples/cluster/): the Slurm job script that
dask-jobqueue writes from examples/cluster/slurm.py, and the Kubernetes manifest's workers
and scheduler ports. No Slurm or Kubernetes here: the script is checked as sbatch would get
it, the manifest as the Dask operator reads it."""
from __future__ import annotations

import importlib.util

import pytest

from paths import ROOT

EXAMPLES = ROOT / "examples" / "cluster"


def _slurm_example():
    spec = importlib.util.spec_from_file_location("slurm_example", EXAMPLES / "slurm.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_slurm_example_submits_one_single_threaded_worker_a_job():
    pytest.importorskip("dask_jobqueue", reason="dask-jobqueue (the test extra) writes the "
                        "Slurm job script")
    c = _slurm_example().cluster(jobs=0, partition="short", memory="3GB", account="robots")
    try:
        script = c.job_script()
        address = c.scheduler_address
    finally:
        c.close()
    assert address.startswith("tcp://")
    lines = script.splitlines()
    assert lines[0].startswith("#!") and "#SBATCH --partition=short" in lines
    assert "#SBATCH --account=robots" in lines and "#SBATCH -n 1" in lines
    assert "#SBATCH --cpus-per-task=1" in lines and "#SBATCH --mem=3G" in lines
    (worker,) = [ln for ln in lines if "distributed.cli.dask_worker" in ln]
    assert f" {address} " in worker and "--nthreads 1 " in worker   # one process, one thread


def test_the_kubernetes_manifest_runs_single_threaded_workers_behind_the_schedulers_port():
    yaml = pytest.importorskip("yaml", reason="PyYAML (dask brings it) reads the manifest")
    doc = yaml.safe_load((EXAMPLES / "kubernetes.yaml").read_text())
    assert (doc["apiVersion"], doc["kind"]) == ("kubernetes.dask.org/v1", "DaskCluster")
    name = doc["metadata"]["name"]
    worker = doc["spec"]["worker"]
    assert worker["replicas"] >= 1
    (wc,) = worker["spec"]["containers"]
    args = [str(a) for a in wc["args"]]
    assert args[:2] == ["dask", "worker"] and args[args.index("--nthreads") + 1] == "1"
    assert wc["resources"]["requests"]["cpu"] == wc["resources"]["limits"]["cpu"] == "1"
    (sc,) = doc["spec"]["scheduler"]["spec"]["containers"]
    assert [str(a) for a in sc["args"]] == ["dask", "scheduler"]
    ports = {p["name"]: p["containerPort"] for p in sc["ports"]}
    assert ports["tcp-comm"] == 8786
    service = doc["spec"]["scheduler"]["service"]
    assert service["selector"] == {"dask.org/cluster-name": name,
                                   "dask.org/component": "scheduler"}
    assert {p["targetPort"] for p in service["ports"]} <= set(ports)
    # the commands in its comments name the service the operator makes of it
    assert f"svc/{name}-scheduler 8786:8786" in (EXAMPLES / "kubernetes.yaml").read_text()
