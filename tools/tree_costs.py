"""The figures behind the tree cost model (symbolic/trees.py): operations after CSE of the planar
chain's kernels in each formulation, and optionally their RK4 step times.

Run: python tools/tree_costs.py [--sizes 2,4,6,8,12,16] [--spherical 1,2] [--steps]

For each n: ops after CSE of the closed form's dynamics and symbolic Jacobian and of the recursive
dynamics (`reduce_expressions`), beside `choose_formulation`'s estimates. With --steps, also ns
per RK4 step (h = 1e-3, best of 5 runs of 10000 steps, process CPU time) of each formulation
compiled with RK4 alone: noisy on a shared machine, so compare within one run only.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from _common import sample_state  # noqa: E402

from lagcodegen import catalog, derive_equations  # noqa: E402
from lagcodegen.codegen.reduce import reduce_expressions  # noqa: E402
from lagcodegen.pipeline import compile_model  # noqa: E402
from lagcodegen.run.simulate import simulate  # noqa: E402
from lagcodegen.symbolic.trees import choose_formulation  # noqa: E402


def ops_after(model, outputs) -> dict:
    system = reduce_expressions(derive_equations(model), outputs, {})
    return {kernel.name: kernel.ops_after for kernel in system.kernels}


def step_ns(model, n: int, steps: int = 10_000) -> float:
    system = compile_model(model, methods=("rk4",), cache_dir=tempfile.mkdtemp(prefix="lcg-tree-costs-"))
    x0, best = sample_state(n), float("inf")
    for _ in range(5):
        start = time.process_time()
        simulate(system, x0, t_end=steps * 1e-3, h=1e-3, stride=steps, check_stability=False)
        best = min(best, time.process_time() - start)
    return 1e9 * best / steps


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="2,4,6,8,12,16")
    parser.add_argument("--spherical", default="", help="spherical_chain sizes (rods), e.g. 1,2")
    parser.add_argument("--steps", action="store_true", help="also time RK4 steps of both formulations")
    options = parser.parse_args(argv)
    for n in (int(v) for v in options.sizes.split(",") if v.strip()):
        chain = catalog.pendulum_chain(n, route="tree")
        closed = ops_after(replace(chain, formulation="closed"), ["rhs", "jacobian"])
        recursive = ops_after(replace(chain, formulation="recursive"), ["rhs"])
        estimate = choose_formulation(chain, implicit=False)
        line = (f"planar n={n}: closed dynamics {closed['dynamics']}, jacobian {closed['jacobian']}; "
                f"recursive {recursive['dynamics']} (estimates: closed {estimate.closed_ops}, "
                f"recursive {estimate.recursive_ops})")
        if options.steps:
            line += (f"; RK4 closed {step_ns(replace(chain, formulation='closed'), n):.0f} ns, recursive "
                     f"{step_ns(replace(chain, formulation='recursive'), n):.0f} ns")
        print(line, flush=True)
    for rods in (int(v) for v in options.spherical.split(",") if v.strip()):
        counts = {f: ops_after(catalog.spherical_chain(rods, formulation=f), ["rhs"])["dynamics"]
                  for f in ("closed", "recursive")}
        print(f"spherical {rods} rods ({3 * rods} joints): closed {counts['closed']}, recursive {counts['recursive']}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
