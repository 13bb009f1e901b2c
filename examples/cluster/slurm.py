"""Workers for `rprs campaign run` as Slurm batch jobs (dask-jobqueue), run on a login node:

    pip install 'rprs[campaign]' dask-jobqueue      # on the login node and the compute nodes
    python examples/cluster/slurm.py --jobs 32 --partition short
    # it prints the scheduler's address; in another shell:
    rprs campaign run study.toml --scheduler tcp://HOST:PORT --workers 32

Each job is one worker process with one thread (a run is single-threaded), `--memory` of
memory; the workers must import the same rprs as the client (the campaign refuses others:
docs/campaigns.md). The cluster lives until Enter is pressed. For PBS, SGE or LSF use
dask-jobqueue's PBSCluster, SGECluster or LSFCluster with the same arguments.
"""
from __future__ import annotations

import argparse


def cluster(jobs: int = 0, partition: str | None = None, memory: str = "2GB",
            walltime: str = "02:00:00", account: str | None = None):
    """A SLURMCluster of one-thread workers, one a job, scaled to ``jobs`` (0: none yet)."""
    from dask_jobqueue import SLURMCluster
    extra = [f"--partition={partition}"] if partition else []
    if account:
        extra.append(f"--account={account}")
    c = SLURMCluster(cores=1, processes=1, memory=memory, walltime=walltime,
                     job_extra_directives=extra,
                     scheduler_options={"port": 0, "dashboard_address": ":0"})
    if jobs:
        c.scale(jobs=jobs)
    return c


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--jobs", type=int, default=8, help="worker jobs to submit (default 8)")
    p.add_argument("--partition", help="Slurm partition (sbatch --partition)")
    p.add_argument("--account", help="Slurm account (sbatch --account)")
    p.add_argument("--memory", default="2GB", help="memory a job (default 2GB)")
    p.add_argument("--walltime", default="02:00:00", help="a job's time limit")
    a = p.parse_args()
    c = cluster(a.jobs, a.partition, a.memory, a.walltime, a.account)
    print(c.job_script())
    print(f"rprs campaign run FILE --scheduler {c.scheduler_address} --workers {a.jobs}")
    input("press Enter to release the workers ")
    c.close()


if __name__ == "__main__":
    main()
