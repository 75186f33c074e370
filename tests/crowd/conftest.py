"""Fixtures of the crowd tests."""
import pytest


@pytest.fixture
def write_scene(tmp_path):
    def write(text, name="scene.toml"):
        p = tmp_path / name
        p.write_text(text)
        return p
    return write


@pytest.fixture(scope="module")
def dask_cluster():
    """A real dask LocalCluster on loopback (two single-threaded worker processes), one per test module
    that asks for it (tests/crowd/test_build.py, report/test_report.py)."""
    from distributed import LocalCluster  # a core dependency: a missing one fails, never skips

    from crowd.report.cluster import shutdown_dask

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        shutdown_dask(cluster=cluster)  # tolerates a slow exit of the workers on a loaded machine
