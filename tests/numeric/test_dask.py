"""`lagcodegen.sweep` on a ``dask.distributed`` cluster, and how workers get the kernel.

Independent source: the same sweep on local threads (`test_sweep.py` checks those members
against `simulate` run alone). Cluster and local runs call the same C function on the same
inputs, so every array must agree bitwise.

A worker unpickles the `CompiledSystem` through ``lagcodegen.build._restore``: it imports the
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

from lagcodegen.build import BuildError, _restore
from lagcodegen.simulate import simulate
from lagcodegen.sweep import sweep

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
    key, _, module_name, layout, sources, lane_build = pendulum.__reduce__()[1]
    rebuilt = _restore(key, str(missing), module_name, layout, sources, lane_build)
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
