"""Dask clusters on SLURM and PBS (dask-jobqueue): the job scripts sweeps submit."""

from __future__ import annotations

import importlib.util
import re
import signal
from pathlib import Path

import pytest
import yaml

from robofleet.core.errors import ConfigError
from robofleet.experiments import batch_cluster
from robofleet.experiments.clusters import import_jobqueue

if importlib.util.find_spec("dask_jobqueue") is None:
    pytest.skip("dask-jobqueue is not installed", allow_module_level=True)
SWEEPS_GUIDE = Path(__file__).resolve().parents[2] / "docs" / "sweeps.md"
ONE_THREAD = ["export OMP_NUM_THREADS=1", "export OPENBLAS_NUM_THREADS=1", "export MKL_NUM_THREADS=1", "export NUMBA_NUM_THREADS=1"]


@pytest.fixture(autouse=True)
def ctrl_c_kept():
    """Building a cluster leaves Ctrl-C as it was (dask-jobqueue's import replaces it)."""
    handler = signal.getsignal(signal.SIGINT)
    yield
    assert signal.getsignal(signal.SIGINT) is handler


@pytest.fixture(autouse=True)
def dashboard_on_a_free_port():
    """Each cluster's scheduler serves its dashboard on a free port rather than dask's fixed
    8787, which another cluster (a test on the other worker) may hold at the same time."""
    import dask

    import_jobqueue()  # its defaults first: the setting below adds to them
    with dask.config.set({f"jobqueue.{system}.scheduler-options": {"dashboard_address": ":0"} for system in ("slurm", "pbs")}):
        yield


def worker_command(script: str) -> str:
    return next(line for line in script.splitlines() if "distributed.cli.dask_worker" in line)


def test_a_slurm_job_runs_one_single_threaded_worker_per_core():
    with batch_cluster("slurm", cores=8, memory="16GB", walltime="02:00:00", queue="compute", account="proj",
                       job_script_prologue=["source ~/env/bin/activate"], job_extra_directives=["--qos=long"]) as cluster:
        script = cluster.job_script()
    for line in ("#SBATCH -p compute", "#SBATCH -A proj", "#SBATCH --cpus-per-task=8", "#SBATCH -t 02:00:00", "#SBATCH --qos=long"):
        assert line in script.splitlines(), script
    command = worker_command(script)
    assert "--nworkers 8" in command and "--nthreads 1" in command
    lines = script.splitlines()
    assert [line for line in lines if line.startswith("export ") or line.startswith("source ")] == [*ONE_THREAD, "source ~/env/bin/activate"]
    assert lines.index("source ~/env/bin/activate") < lines.index(command)


def test_a_pbs_job_asks_for_the_cores_and_memory():
    with batch_cluster("pbs", cores=4, memory="8GB", walltime="00:30:00", queue="workq", account="proj") as cluster:
        script = cluster.job_script()
    lines = script.splitlines()
    assert "#PBS -q workq" in lines and "#PBS -A proj" in lines and "#PBS -l walltime=00:30:00" in lines
    assert any(re.fullmatch(r"#PBS -l select=1:ncpus=4:mem=\d+[MG]B", line) for line in lines), script
    assert "--nworkers 4" in worker_command(script) and "--nthreads 1" in worker_command(script)
    assert all(line in lines for line in ONE_THREAD)


def test_the_profiles_in_the_sweeps_guide_build_the_job_scripts_it_describes():
    import dask

    jobqueue = import_jobqueue()
    blocks = re.findall(r"```yaml\n(.*?)```", SWEEPS_GUIDE.read_text(), flags=re.S)
    profile = next(yaml.safe_load(block) for block in blocks if "jobqueue" in block)
    settings = {f"jobqueue.{system}.{key}": value for system, keys in profile["jobqueue"].items() for key, value in keys.items()}
    with dask.config.set(settings):  # on top of dask-jobqueue's defaults, as a configuration file is
        with jobqueue.SLURMCluster() as slurm:
            slurm_script = slurm.job_script()
        with jobqueue.PBSCluster() as pbs:
            pbs_script = pbs.job_script()
    for script in (slurm_script, pbs_script):
        assert "--nworkers 32" in worker_command(script) and "--nthreads 1" in worker_command(script)
        assert all(line in script.splitlines() for line in ONE_THREAD)
    assert "#SBATCH -p compute" in slurm_script and "#SBATCH -t 04:00:00" in slurm_script
    assert "#PBS -q workq" in pbs_script and "#PBS -l walltime=04:00:00" in pbs_script


@pytest.mark.parametrize("kwargs, words", [({"system": "lsf"}, "system: expected one of ['pbs', 'slurm']"),
                                            ({"system": "slurm", "cores": 0}, "cores: expected an integer ≥ 1")])
def test_bad_cluster_arguments_are_refused_in_one_line(kwargs, words):
    arguments = {"cores": 2, "memory": "1GB", **kwargs}
    with pytest.raises(ConfigError) as info:
        batch_cluster(arguments.pop("system"), **arguments)
    assert str(info.value).startswith(words) and "\n" not in str(info.value)
