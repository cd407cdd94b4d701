"""Helpers shared by the `kernels` and `integrators` suites (not a suite itself: no ``bench_``).

Worker side: `render` (one prefixed JSON message per phase, the protocol of
`bench_derive.run_in_subprocess`), `best_seconds` (minimum over repeats), the models by
tag, `rhs_harness` (a C loop over a compiled rhs, so per-evaluation costs are measured in C),
`count_c_ops` and `pydy_chain_rhs`. Parent side: `run_worker` (a fresh process under hard
time-outs, messages merged into one dict), `format_table` and `peer_versions`.
Standard library only at module level, like the suites.
"""
from __future__ import annotations

import json
import re
import sys
import tempfile
import time
from pathlib import Path

from bench_derive import MESSAGE_PREFIX, run_in_subprocess

HERE = Path(__file__).resolve().parent
DP = "dp"  # model tag of the double pendulum; an int tag n is pendulum_chain(n)
DP_STATE = (1.0, 0.5, 0.0, 0.0)  # q1, q2, u1, u2: regular enough for a 1e-12 reference over 10 s


# -- worker side ---------------------------------------------------------------------------------
def emit(**message) -> None:
    print(MESSAGE_PREFIX + json.dumps(message), flush=True)


def best_seconds(fn, repeat: int) -> float:
    """Minimum wall time (perf_counter) of ``repeat`` calls of ``fn()``: the machine is shared,
    so the fastest run is the least disturbed one."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def best_seconds_interleaved(fns, repeat: int) -> list:
    """`best_seconds` of each of ``fns``, their calls taken in turn (a, b, a, b, ...): a ratio of
    two best times then compares runs under the same load of the shared machine, where measuring
    one side's repeats before the other's can put a busy spell on either side."""
    best = [float("inf")] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            start = time.perf_counter()
            fn()
            best[i] = min(best[i], time.perf_counter() - start)
    return best


def per_call_seconds(fn, repeat: int, target: float = 0.05) -> float:
    """Best time per call of ``fn(number)`` (which makes ``number`` calls), ``number`` grown
    until one run lasts ``target`` seconds."""
    number = 1
    while True:
        start = time.perf_counter()
        fn(number)
        if time.perf_counter() - start >= target or number >= 1 << 30:
            break
        number *= 4
    return best_seconds(lambda: fn(number), repeat) / number


def model_of(tag):
    """The catalog model for a tag: ``"dp"`` the double pendulum, an int n the n-link chain."""
    from lagcodegen.catalog import double_pendulum, pendulum_chain

    return double_pendulum() if tag == DP else pendulum_chain(int(tag))


def links(tag) -> int:
    return 2 if tag == DP else int(tag)


def parse_tag(text: str):
    return DP if text == DP else int(text)


def label(tag) -> str:
    return "double pendulum" if tag == DP else f"chain n={tag}"


def sample_state(n: int, seed: int = 0):
    """A fixed state (2n,) with angles in (-1, 1) rad and speeds in (-1, 1) rad/s."""
    import numpy as np

    return np.random.default_rng(seed).uniform(-1.0, 1.0, 2 * n)


_HARNESS = """\
#include "{header}"
{hand_decls}
void bench_{who}_independent(const double *X, long n_states, const double *p, long reps, double *out)
{{
    long r, k;
    for (r = 0; r < reps; ++r)
        for (k = 0; k < n_states; ++k)
            (void){rhs}(0.0, X + k * {N}, p, out + k * {N});
}}

void bench_{who}_chained(double *x, const double *p, double h, long n_evals)
{{
    double xdot[{N}];
    long k;
    int i;
    for (k = 0; k < n_evals; ++k) {{
        (void){rhs}(0.0, x, p, xdot);
        for (i = 0; i < {N}; ++i) x[i] += h * xdot[i];
    }}
}}
"""
_HARNESS_CDEF = """\
void bench_{who}_independent(const double *X, long n_states, const double *p, long reps, double *out);
void bench_{who}_chained(double *x, const double *p, double h, long n_evals);
"""


def rhs_harness(sources, with_hand: bool):
    """A cffi module looping over the generated rhs (and the hand-written one) in C.

    The generated ``.c`` and ``hand_double_pendulum.c`` are separate translation units, both
    compiled with lagcodegen's flags (``peers.default_flags``): every evaluation is a real call, as from an
    integrator in another file, and nothing is inlined or hoisted out of the loop.
    ``bench_<who>_independent`` evaluates ``reps`` times at each of ``n_states`` states
    (throughput); ``bench_<who>_chained`` takes explicit Euler steps x += h f(x), so each
    evaluation waits for the previous one (latency). ``who`` is ``lcg`` or ``hand``.
    """
    from peers import HAND_DP_CDEF, HAND_DP_SOURCE, build_cffi

    n_state = 2 * sources.layout.n
    rhs = {"lcg": f"{sources.layout.prefix}_rhs", "hand": "hand_dp_rhs"}
    whos = ["lcg", "hand"] if with_hand else ["lcg"]
    text = "".join(_HARNESS.format(header=sources.header_name, hand_decls=HAND_DP_CDEF if who == "hand" else "",
                                   who=who, rhs=rhs[who], N=n_state) for who in whos)
    cdef = "".join(_HARNESS_CDEF.format(who=who) for who in whos)
    with tempfile.TemporaryDirectory(prefix="lcg-harness-") as tmp:
        tmp = Path(tmp)
        (tmp / sources.header_name).write_text(sources.header)
        (tmp / sources.source_name).write_text(sources.source)
        files = [tmp / sources.source_name] + ([HAND_DP_SOURCE] if with_hand else [])
        return build_cffi("_lcg_bench_harness", cdef, text, sources=files, include_dirs=[tmp])


def _call_count(fn, target: float = 0.05) -> int:
    """The number of calls ``fn(number)`` needs to last ``target`` seconds (grown by 4)."""
    number = 1
    while True:
        start = time.perf_counter()
        fn(number)
        if time.perf_counter() - start >= target or number >= 1 << 30:
            return number
        number *= 4


def c_ns_per_eval_interleaved(module, whos, X, p, repeat: int) -> dict:
    """`c_ns_per_eval` of each of ``whos`` ("hand", "lcg"), every timed run taken in turn with the
    others' (found by review: hand C timed before ours put a busy spell on one side only, and the
    1.1x goal was decided by it)."""
    import numpy as np

    ffi, lib = module.ffi, module.lib
    X = np.ascontiguousarray(X, dtype=float)
    out = np.empty_like(X)
    k = X.shape[0]
    pX, pp, pout = (ffi.from_buffer("double[]", a) for a in (X, np.ascontiguousarray(p, float), out))
    x = X[0].copy()
    px = ffi.from_buffer("double[]", x)
    runs = []  # (who, mode, fn(number), evaluations per call)
    for who in whos:
        independent, chained = getattr(lib, f"bench_{who}_independent"), getattr(lib, f"bench_{who}_chained")

        def run_chained(number, chained=chained):
            x[:] = X[0]
            chained(px, pp, 1e-5, number)
        runs += [(who, "independent", lambda r, f=independent: f(pX, k, pp, r, pout), k),
                 (who, "chained", run_chained, 1)]
    counts = [_call_count(fn) for _, _, fn, _ in runs]
    best = best_seconds_interleaved([lambda fn=fn, n=n: fn(n) for (_, _, fn, _), n in zip(runs, counts)], repeat)
    found: dict = {who: {} for who in whos}
    for (who, mode, _, per), n, seconds in zip(runs, counts, best):
        found[who][mode] = 1e9 * seconds / n / per
    return found


def c_ns_per_eval(module, who: str, X, p, repeat: int) -> dict:
    """ns per rhs evaluation in the harness: ``independent`` (X: (k, 2n) states) and ``chained``."""
    import numpy as np

    ffi, lib = module.ffi, module.lib
    X = np.ascontiguousarray(X, dtype=float)
    out = np.empty_like(X)
    k = X.shape[0]
    pX, pp, pout = (ffi.from_buffer("double[]", a) for a in (X, np.ascontiguousarray(p, float), out))
    independent = getattr(lib, f"bench_{who}_independent")
    chained = getattr(lib, f"bench_{who}_chained")
    x = X[0].copy()
    px = ffi.from_buffer("double[]", x)

    def run_chained(number):
        x[:] = X[0]
        chained(px, pp, 1e-5, number)
    return {"independent": 1e9 * per_call_seconds(lambda r: independent(pX, k, pp, r, pout), repeat) / k,
            "chained": 1e9 * per_call_seconds(run_chained, repeat)}


def pydy_chain_rhs(n: int):
    """KanesMethod chain (bench_derive's peer model, u = qd) and PyDy's Cython rhs
    ``f(x, t, p)``; returns (f, seconds of Kane derivation, seconds of generate + compile)."""
    import sympy as sp
    from bench_derive import _sympy_chain
    from pydy.codegen.ode_function_generators import generate_ode_function

    start = time.perf_counter()
    M, F, q, u, params = _sympy_chain(n, kane=True)
    derived = time.perf_counter()
    f = generate_ode_function(F, q, u, params, mass_matrix=M, coordinate_derivatives=sp.Matrix(u),
                              generator="cython", constants_arg_type="array")
    return f, derived - start, time.perf_counter() - derived


_NUMBER = re.compile(r"(?<![\w.])(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?[fFlL]?")
_CALL = re.compile(r"\b[A-Za-z_]\w*\s*\(")
_ASSIGN = re.compile(r"^(?:const\s+)?(?:double\s+)?[\w\[\]]+\s*=\s*(.+)$")


def count_c_ops(text: str) -> int:
    """Arithmetic operations in the C assignment statements of ``text``: each ``+ - * /`` (unary
    minus too) and each function call (``sin(``, ``pow(``) counts 1; literals, indexing and
    copies count 0; statements may span lines (PyDy wraps them)."""
    total = 0
    for statement in re.sub(r"/\*.*?\*/", " ", text, flags=re.S).split(";"):
        match = _ASSIGN.match(" ".join(statement.split()))
        if match:
            rhs = _NUMBER.sub("N", match.group(1))
            total += len(_CALL.findall(rhs)) + len(re.findall(r"[-+*/]", rhs))
    return total


# -- parent side ---------------------------------------------------------------------------------
def run_messages(script: str, args: list, timeouts: list, env: dict | None = None) -> tuple[list, str]:
    """Run ``script --worker *args`` in a fresh process, with ``env`` added to its environment;
    phase i limited to timeouts[i] s. Returns (messages, status) as `run_in_subprocess`."""
    import os

    argv = [sys.executable, str(Path(script).resolve()), "--worker", *map(str, args)]
    if env is None:
        return run_in_subprocess(argv, timeouts)
    saved = dict(os.environ)
    os.environ.update(env)  # run_in_subprocess's Popen inherits os.environ
    try:
        return run_in_subprocess(argv, timeouts)
    finally:
        os.environ.clear()
        os.environ.update(saved)


def run_worker(script: str, args: list, timeouts: list, env: dict | None = None) -> dict:
    """`run_messages`, the messages merged into one dict plus ``status`` ("ok", "timeout" or
    "error: ...")."""
    messages, status = run_messages(script, args, timeouts, env)
    merged = {"status": status}
    for message in messages:
        merged.update({k: v for k, v in message.items() if k != "phase"})
    return merged


def progress(text: str) -> None:
    print("  " + text, file=sys.stderr, flush=True)


def format_table(header: list, body: list, left: int = 1) -> str:
    """Plain-text table; the first ``left`` columns left-aligned, the rest right-aligned."""
    cells = [[str(c) for c in row] for row in [header] + body]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    line = lambda row: "  ".join(c.ljust(w) if i < left else c.rjust(w)  # noqa: E731
                                 for i, (c, w) in enumerate(zip(row, widths))).rstrip()
    return "\n".join([line(cells[0]), line(["-" * w for w in widths])] + [line(r) for r in cells[1:]])


def fmt(value, spec: str, missing: str = "-") -> str:
    return missing if value is None else format(value, spec)


def peer_versions(*names) -> str:
    """``name version`` for each installed distribution, comma separated."""
    from importlib.metadata import PackageNotFoundError, version

    parts = []
    for name in names:
        try:
            parts.append(f"{name} {version(name)}")
        except PackageNotFoundError:
            parts.append(f"{name} (not installed)")
    return ", ".join(parts)


def compiler_version() -> str:
    import subprocess
    import sysconfig

    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except OSError:
        return cc
    return out.splitlines()[0] if out else cc
