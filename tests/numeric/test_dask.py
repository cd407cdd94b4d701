"""`lagcodegen.run.sweep` on a ``dask.distributed`` cluster, and how workers get the kernel.

Independent source: the same sweep on local threads (`test_sweep.py` checks those members
against `simulate` run alone). Cluster and local runs call the same C function on the same
inputs, so every array must agree bitwise.

A worker unpickles the `CompiledSystem` through ``lagcodegen.native.build._restore``: it imports the
``.so`` at the pickled path, or, on a machine where that path does not exist, rebuilds the
kernel from the pickled C sources with `build_module` (into the worker's own cache). The
second case is checked in-process with an isolated ``LAGCODEGEN_CACHE_DIR``.
"""
from __future__ import annotations

import dataclasses
import os
import pickle

import numpy as np
import pytest
from numpy.testing import assert_array_equal

import lagcodegen.run.sweep as sweep_module
from lagcodegen.native.build import BuildError, _restore
from lagcodegen.run.simulate import simulate
from lagcodegen.run.sweep import CHUNK_FAILED, SweepWarning, sweep

pytestmark = pytest.mark.compiler

X0 = (0.6, -0.4, 0.0, 0.3)
GRID = {"m2": (-0.5, 0.5, 1.0, 2.0), "q1": tuple(np.linspace(-1.2, 1.2, 5))}  # 20 members, 5 failing
RUN = dict(x0=X0, t0=0.25, t_end=2.25, h=0.01, trajectories=True, stride=10)
FIELDS = ("values", "x_final", "q_max", "energy_error", "status", "steps_done", "blowup_time", "t",
          "trajectories")


@pytest.fixture(scope="module")
def pendulum(compiled_example):
    return compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=("rk4",))


@pytest.fixture(scope="module")
def distributed():
    """``dask.distributed``; skipped when missing, except with ``$CI`` set (it is in the test
    extras, so a CI image without it is broken: fail, as ``require_tool`` in conftest does)."""
    try:
        import dask.distributed
    except ImportError as exc:
        if os.environ.get("CI"):
            pytest.fail(f"dask.distributed is not importable ({exc}); CI is set: install the "
                        f"'dask' extra instead of skipping")
        pytest.skip(f"dask.distributed is not importable: {exc}")
    return dask.distributed


def test_cluster_sweep_equals_local_sweep(pendulum, distributed):
    local = sweep(pendulum, GRID, threads=2, **RUN)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        # chunk_size 3: 7 tasks over 2 worker processes, the last one short
        remote = sweep(pendulum, GRID, client=client, chunk_size=3, **RUN)
        workers = client.run(os.getpid)
    assert len(set(workers.values()) - {os.getpid()}) == 2  # really two other processes
    assert remote.completed and remote.columns == local.columns
    for name in FIELDS:
        assert_array_equal(getattr(remote, name), getattr(local, name), err_msg=name)
    assert np.count_nonzero(local.status) == len(GRID["q1"])  # the m2 < 0 row failed on both


def test_restore_rebuilds_when_the_module_path_is_missing(pendulum, tmp_path, monkeypatch):
    cache = tmp_path / "worker_cache"
    monkeypatch.setenv("LAGCODEGEN_CACHE_DIR", str(cache))
    # what a worker on the same machine gets: the module at the pickled path
    same_host = pickle.loads(pickle.dumps(pendulum))
    assert same_host.path == pendulum.path and same_host.key == pendulum.key

    # what a worker on another machine gets: a path that does not exist there, plus the sources
    missing = tmp_path / "elsewhere" / pendulum.path.name
    assert not missing.exists() and pendulum.sources is not None
    key, _, module_name, layout, sources, lane_build, *machine = pendulum.__reduce__()[1]
    rebuilt = _restore(key, str(missing), module_name, layout, sources, lane_build, *machine)
    assert (rebuilt.lane_build is None) == (pendulum.lane_build is None)  # the lane kernel can follow
    assert rebuilt.path.is_file() and cache in rebuilt.path.parents  # built into its own cache
    assert rebuilt.key == pendulum.key and rebuilt.module_name == pendulum.module_name
    assert rebuilt.layout == pendulum.layout

    # the same through pickle (a CompiledSystem whose .so lives "elsewhere")
    moved = dataclasses.replace(pendulum, path=missing)
    unpickled = pickle.loads(pickle.dumps(moved))
    assert unpickled.path == rebuilt.path

    # the rebuilt kernel computes what the original does
    want = simulate(pendulum, X0, 1.0, 0.01, params={"m2": 1.3}, energy=True)
    for system in (rebuilt, unpickled):
        got = simulate(system, X0, 1.0, 0.01, params={"m2": 1.3}, energy=True)
        assert_array_equal(got.x, want.x)
        assert_array_equal(got.energy, want.energy)
    assert_array_equal(sweep(rebuilt, GRID, **RUN).x_final, sweep(pendulum, GRID, **RUN).x_final)

    # without sources there is nothing to rebuild from: a clear error, not an ImportError
    with pytest.raises(BuildError, match="no longer exists"):
        _restore(key, str(missing), module_name, layout, None)


def test_a_failed_task_keeps_the_other_chunks(pendulum, distributed, monkeypatch):
    """One task raises on the cluster (a bug in a chunk, reaching the client as its own
    exception). Before, ``future.result()`` raised out of sweep() and the finished chunks were
    lost. Now the failed chunks' members are CHUNK_FAILED and every other member equals the
    local sweep (the independent reference).

    An in-process cluster (processes=False: in-process transport, no network port): its worker
    threads call the same module-level ``run_chunk`` -> ``_call`` real tasks call, with ``_call``
    failing for chunks holding a member with q1 = 0 (members 2, 7, 12, 17; chunk_size 3)."""
    local = sweep(pendulum, GRID, threads=2, **RUN)
    real_call = sweep_module._call

    def call(job, xs, ps, out):
        if np.any(xs[:, 0] == 0.0):
            raise ZeroDivisionError("chunk bug")
        real_call(job, xs, ps, out)

    monkeypatch.setattr(sweep_module, "_call", call)
    chunks = sorted({m // 3 for m in np.flatnonzero(local.values[:, 1] == 0.0)})
    assert chunks == [0, 2, 4, 5]
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        with pytest.warns(SweepWarning) as caught:
            remote = sweep(pendulum, GRID, client=client, chunk_size=3, **RUN)
    caught = [w for w in caught if issubclass(w.category, SweepWarning)]  # not m2 < 0's sign warning
    assert {str(w.message).split(" failed")[0] for w in caught} == \
        {f"sweep chunk of members {3 * c} to {3 * c + 2}" for c in chunks} and len(caught) == len(chunks)
    assert all("(ZeroDivisionError: chunk bug)" in str(w.message) for w in caught)
    failed = np.zeros(remote.n_members, bool)
    for chunk in chunks:
        failed[3 * chunk:3 * chunk + 3] = True
    assert not remote.completed
    assert sorted((e.start, e.stop, e.error) for e in remote.errors) == \
        [(3 * c, 3 * c + 3, "ZeroDivisionError: chunk bug") for c in chunks]
    assert_kept_members_equal(remote, local, failed)


def assert_kept_members_equal(remote, local, failed):
    """Members of failed chunks are CHUNK_FAILED with NaN results; the others equal ``local``."""
    assert_array_equal(remote.status[failed], CHUNK_FAILED)
    assert np.all(np.isnan(remote.x_final[failed])) and np.all(np.isnan(remote.trajectories[failed]))
    for name in FIELDS:
        if name not in ("values", "t"):
            assert_array_equal(getattr(remote, name)[~failed], getattr(local, name)[~failed], err_msg=name)
    assert_array_equal(remote.values, local.values)


def test_a_killed_worker_keeps_the_other_chunks(pendulum, distributed):
    """A worker process really dies (``os._exit`` in the chunk holding q1 = 0, installed in the
    worker with ``client.run``; a nested function, so cloudpickle ships it by value). With
    allowed-failures = 0 the scheduler gives up on every task that was on the dead worker: the
    client sees ``KilledWorker`` for those chunks. Which chunks were on it depends on scheduling,
    so the test checks the invariant: exactly the chunks listed in ``errors`` are CHUNK_FAILED,
    the one that killed the worker is among them, and every other member equals the local sweep
    (the restarted worker has the real ``_call`` again)."""
    import dask

    local = sweep(pendulum, GRID, threads=2, **RUN)

    def install_killer():
        import os as os_

        import numpy as np_

        import lagcodegen.run.sweep as module
        real_call = module._call

        def call(job, xs, ps, out):
            if np_.any(xs[:, 0] == 0.0) and np_.any(xs[:, 0] < 0.0):  # chunk 0 only: members 0..2
                os_._exit(1)
            real_call(job, xs, ps, out)

        module._call = call

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                     dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        client.run(install_killer)
        with pytest.warns(SweepWarning) as caught:
            remote = sweep(pendulum, GRID, client=client, chunk_size=3, **RUN)
    caught = [w for w in caught if issubclass(w.category, SweepWarning)]  # not m2 < 0's sign warning
    assert any("members 0 to 2 failed (KilledWorker" in str(w.message) for w in caught)
    assert len(caught) == len(remote.errors)
    failed = np.zeros(remote.n_members, bool)
    for error in remote.errors:
        assert error.error.startswith("KilledWorker")
        failed[error.start:error.stop] = True
    assert not remote.completed and failed[:3].all() and not failed.all()
    assert_kept_members_equal(remote, local, failed)


def test_a_worker_without_lagcodegen_is_named_before_anything_runs(pendulum, distributed):
    """A worker whose environment cannot import lagcodegen (made so here by ``sys.modules[...] =
    None`` in the worker process, which makes that import raise ModuleNotFoundError). Before, the
    worker died unpickling its first chunk, its nanny restarted it, and sweep() waited for ever
    (reproduced with a ``dask worker`` started without lagcodegen on its path, 2026-11-26). Now
    sweep() raises at once, naming the worker and the import that failed."""
    def without_lagcodegen():
        import sys as sys_
        sys_.modules["lagcodegen.run.sweep"] = None

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        client.run(without_lagcodegen)
        worker = next(iter(client.scheduler_info()["workers"]))
        with pytest.raises(RuntimeError, match=rf"dask worker {worker} cannot import lagcodegen.run.sweep "
                                               r"\(ModuleNotFoundError.*nothing was run"):
            sweep(pendulum, GRID, client=client, chunk_size=3, **RUN)


def test_a_worker_with_another_version_is_named(pendulum, distributed):
    """A worker whose lagcodegen reports another version (set in the worker process): its kernels
    and chunk format may differ, so sweep() refuses, naming both versions."""
    def other_version():
        import lagcodegen
        lagcodegen.__version__ = "0.0.1-other"

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        client.run(other_version)
        with pytest.raises(RuntimeError, match=r"has another lagcodegen \(0.0.1-other\) than this process"):
            sweep(pendulum, GRID, client=client, chunk_size=3, **RUN)


def test_a_cluster_without_workers_is_named(pendulum, distributed, monkeypatch):
    """Found by review: with no worker, the version check passed on an empty answer and the sweep waited
    for ever. No worker may join: after WORKER_WAIT (here 1 s) the sweep says so, having run nothing."""
    monkeypatch.setattr(sweep_module, "WORKER_WAIT", 1.0)
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        with pytest.raises(RuntimeError, match="has no worker"):
            sweep(pendulum, GRID, client=client, **RUN)


def test_the_default_chunks_count_the_cluster_threads(pendulum, distributed, monkeypatch):
    """Found by review (session 16): the default chunk size counted the client's cores (2 here), so
    1000 members became 8 tasks on a 12-thread cluster and at most 8 of its threads ever ran. By
    hand: about 4 chunks per cluster thread, 48 for 12 threads (fewer only by the rounding of a
    chunk up to whole lane groups). The members' results are the local sweep's (bitwise)."""
    sizes = []
    real_call = sweep_module._call

    def call(job, xs, ps, out):
        sizes.append(len(xs))
        real_call(job, xs, ps, out)

    grid = {"m2": tuple(np.linspace(0.5, 2.0, 40)), "q1": tuple(np.linspace(-1.0, 1.0, 25))}  # 1000 members
    run = dict(x0=X0, t_end=0.05, h=0.01)
    local = sweep(pendulum, grid, threads=2, **run)
    monkeypatch.setattr(sweep_module, "_call", call)
    with distributed.LocalCluster(n_workers=6, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = sweep(pendulum, grid, client=client, **run)
    assert sum(sizes) == 1000 and len(sizes) >= 40, sizes
    assert_array_equal(remote.x_final, local.x_final)
