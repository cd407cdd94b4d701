"""Stage: EquationsOfMotion -> ReducedSystem (one ReducedKernel per C output function).

Common subexpressions are eliminated jointly over everything one kernel outputs: the
``dynamics`` kernel, behind the C ``accel`` and ``rhs`` functions, shares temporaries between K, M
and F. Fixed parameters fold in two steps: those fixed at 0 or 1 before CSE (they only remove
operations), the others after it, where every temporary that reads nothing but fixed parameters
becomes its value and the parameters themselves become named constants. Substituted before CSE,
a number multiplying a sum is distributed over it by sympy (2.0*(x + y) -> 2.0*x + 2.0*y): the
Whipple bicycle's dynamics kernel took 1704 operations with its 27 benchmark parameters folded
that way, 1393 with none folded and 1363 folded after CSE. Numbers folded before CSE can also
combine terms (the centrifugal governor's dynamics: 13 operations against 26 after CSE), so both
are built and the cheaper kept.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import sympy as sp
from sympy.core.operations import LatticeOp
from sympy.simplify.radsimp import fraction

try:  # count_ops's own test for a negative coefficient (private in sympy; absent: count_ops itself)
    from sympy.core.function import _coeff_isneg
except ImportError:  # pragma: no cover
    _coeff_isneg = None

from ..symbolic.derive import EquationsOfMotion
from ..walk import free_symbols_of
from .outputs import DEFAULT_OUTPUTS, KERNEL_ROWS, OUTPUTS, KernelError, checked_outputs


@dataclass(frozen=True)
class ReducedKernel:
    """Straight-line code for one output function.

    Attributes
    ----------
    name : str
        A key of `outputs.KERNEL_ROWS` (``dynamics`` is behind accel, rhs and multipliers).
    temporaries : tuple of (Symbol, Expr)
        In evaluation order; each may use inputs and earlier temporaries.
    results : tuple of (label, Expr)
        ``label`` is (block, i, j), the labels of `outputs` (module docstring).
    ops_before, ops_after : int
        ``sympy.count_ops`` of the results before CSE, and of temporaries plus results after.
    """

    name: str
    temporaries: tuple
    results: tuple
    ops_before: int
    ops_after: int

    @property
    def symbols(self) -> frozenset:
        """Free symbols the kernel reads (inputs only, temporaries excluded)."""
        found = set()
        for _, expr in self.temporaries + self.results:
            found |= expr.free_symbols
        return frozenset(found - {s for s, _ in self.temporaries})


@dataclass(frozen=True)
class ReducedSystem:
    """Everything emission needs: symbol order, parameter split and the kernels.

    ``kinematics_identity`` is True when qd = u (every Lagrange route), so the C copies u.
    ``accelerations`` are the symbols a_j standing for ud_j in the jacobian kernel.
    ``n_constraints`` is m, the number of constraints with multipliers (0 when they are eliminated),
    ``n_holonomic`` how many of them, first, are holonomic.
    ``u`` are the speeds in the state; ``u_dependent`` those eliminated by the velocity constraints
    (computed from them in C at every evaluation; M and F are over ``u + u_dependent``).
    ``inputs`` are the symbols of the inputs r (``r[i]`` in C), in the model's order;
    ``measurements`` the names of the model's output expressions y = h(q, u, r, t).
    ``ops_saved_by_fixing`` counts operations removed by folding fixed parameters (before CSE for the
    values folded before it, after CSE for those folded after it).
    ``recursive``: a tree's kernels are its recursive algorithm's assignments (`symbolic.trees`),
    whose own names stand in for CSE temporaries; ``formulation`` says how and why.
    """

    name: str
    route: str
    t: sp.Symbol
    q: tuple
    u: tuple
    accelerations: tuple
    free_parameters: tuple
    fixed_parameters: tuple
    parameter_values: dict
    point_names: tuple
    outputs: tuple
    kernels: tuple
    kinematics_identity: bool
    ops_saved_by_fixing: int
    n_constraints: int = 0
    n_holonomic: int = 0
    inputs: tuple = ()
    measurements: tuple = ()
    u_dependent: tuple = ()
    reactions: tuple = ()
    dependent_coordinates: tuple = ()
    formulation: str = ""
    recursive: bool = False
    angle_coordinates: tuple = ()  # a recursive tree's: coordinate j moves revolute joints only

    def kernel(self, name: str) -> ReducedKernel:
        for k in self.kernels:
            if k.name == name:
                return k
        raise KeyError(f"kernel {name!r} was not requested (outputs: {', '.join(self.outputs)})")


def reduce_expressions(eom: EquationsOfMotion, outputs=DEFAULT_OUTPUTS,
                       fixed: Mapping | None = None) -> ReducedSystem:
    """Fold ``fixed`` parameters and CSE each requested output's kernel.

    Parameters
    ----------
    eom : EquationsOfMotion
    outputs : sequence of str
        Names of `outputs.OUTPUTS` (default ``DEFAULT_OUTPUTS``); only these are generated.
    fixed : mapping parameter (Symbol or name) -> float, optional
        Parameters folded into the code; every other parameter stays a runtime input ``p[i]``.
    """
    outputs = checked_outputs(eom, outputs)
    fixed_values = _checked_fixed(eom, fixed or {})
    folding = {p: sp.Float(v, 17) for p, v in fixed_values}
    removing = {p: sp.Integer(int(v)) for p, v in fixed_values if v in (0.0, 1.0)}
    constants = {p: value for p, value in folding.items() if p not in removing}
    accelerations = tuple(sp.Dummy(f"{s.name}_dd") for s in eom.u)
    blocks = _output_blocks(eom, outputs, accelerations)
    saved = 0
    kernels = []
    for name in TREE_KERNELS if eom.tree is not None else ():
        if name in blocks:
            del blocks[name]
            kernels.append(_tree_kernel(eom, name, folding))
    for name, labelled in blocks.items():
        raw = [expr for _, expr in labelled]
        labels = [label for label, _ in labelled]
        if not folding:
            kernels.append(_reduce(name, labels, raw)[0])
            continue
        folded = [expr.xreplace(folding) for expr in raw]
        _check_folded(eom, labelled, raw, folded, fixed_values)
        early = [expr.xreplace(removing) for expr in raw] if removing else raw
        kernel, saved_late = _reduce(name, labels, early, constants)  # also folds cos(1) of a value 1
        candidates = [(kernel, count_operations(raw) - count_operations(early) + saved_late)]
        if constants:  # numbers folded before CSE can also combine terms: keep whichever is cheaper
            before_cse = _reduce(name, labels, folded, {})[0]
            candidates.insert(0, (before_cse, count_operations(raw) - count_operations(folded)))
        kernel, kernel_saved = min(candidates, key=lambda pair: pair[0].ops_after)
        kernels.append(kernel)
        saved += kernel_saved
    independent = eom.n_u - eom.n_dependent
    kinematics_identity = list(eom.kinematics) == list(eom.u) and not eom.n_dependent
    fixed_symbols = {p for p, _ in fixed_values}
    return ReducedSystem(
        name=eom.name, route=eom.route, t=eom.t, q=eom.q, u=eom.u[:independent], accelerations=accelerations,
        u_dependent=eom.u[independent:], reactions=tuple(eom.reactions) if "reactions" in outputs else (),
        dependent_coordinates=tuple(eom.dependent_coordinates) if "configuration" in outputs else (),
        free_parameters=tuple(p for p in eom.parameters if p not in fixed_symbols),
        fixed_parameters=fixed_values, parameter_values=dict(eom.parameter_values),
        point_names=tuple(name for name, _ in eom.points),
        outputs=tuple(outputs), kernels=tuple(kernels), kinematics_identity=kinematics_identity,
        ops_saved_by_fixing=int(saved), n_constraints=0 if eom.n_dependent else eom.m,
        n_holonomic=0 if eom.n_dependent else eom.n_holonomic, inputs=tuple(eom.inputs),
        measurements=tuple(name for name, _ in eom.measurements) if "measurements" in outputs else (),
        formulation=eom.formulation, recursive=eom.tree is not None,
        angle_coordinates=tuple(eom.tree.angles) if eom.tree is not None else ())


def _check_folded(eom: EquationsOfMotion, labelled, raw, folded, fixed_values) -> None:
    """A KernelError naming the fixed values when folding them leaves an entry undefined (zoo or nan:
    log(L) at L = 0, 1 / k at k = 0) or not real (sqrt(L - 2) at L = 1), where the C printer would
    have named only the entry."""
    for (label, _), before, after in zip(labelled, raw, folded):
        undefined = [a for a in (sp.zoo, sp.nan, sp.oo, -sp.oo, sp.I) if after.has(a) and not before.has(a)]
        if undefined:
            values = ", ".join(f"{p.name} = {v!r}" for p, v in fixed_values)
            entry = f"{label[1]}" + (f", {label[2]}" if len(label) > 2 and label[2] != 0 else "")
            what = "not real (sqrt or log of a negative number)" if undefined[0] is sp.I else "undefined"
            raise KernelError(f"model {eom.name!r}: with {values} folded in, {label[0]}[{entry}] is {what} "
                              f"({undefined[0]}); fix those parameters to other values, or leave them free")


def _checked_fixed(eom: EquationsOfMotion, fixed: Mapping) -> tuple:
    by_name = {p.name: p for p in eom.parameters}
    values = []
    for key, value in fixed.items():
        name = key.name if isinstance(key, sp.Symbol) else str(key)
        if name not in by_name:
            raise KernelError(f"cannot fix {name!r}: not a parameter of {eom.name!r} "
                              f"(parameters: {', '.join(by_name)})")
        if isinstance(value, (bool, str, bytes)):
            raise KernelError(f"fixed parameter {name!r} must be a real number, got {type(value).__name__} {value!r}")
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise KernelError(f"fixed parameter {name!r} must be a real number, got "
                              f"{type(value).__name__} {value!r}") from None
        if value != value or value in (float("inf"), float("-inf")):
            raise KernelError(f"fixed parameter {name!r} has a non-finite value {value}")
        values.append((by_name[name], value))
    order = {p: i for i, p in enumerate(eom.parameters)}
    return tuple(sorted(values, key=lambda pv: order[pv[0]]))


def _output_blocks(eom: EquationsOfMotion, outputs, accelerations) -> dict:
    """kernel name -> [(label, expr)], in the order of the outputs that need them (a tree's
    recursive kernels: None, see `_tree_kernel`)."""
    blocks: dict = {}
    for name in outputs:
        kernel = OUTPUTS[name].kernel
        if kernel not in blocks:
            recursive = eom.tree is not None and kernel in TREE_KERNELS
            blocks[kernel] = None if recursive else KERNEL_ROWS[kernel](eom, accelerations)
    return blocks


#: kernels a tree's recursive formulation writes from its assignments (the jacobian: finite
#: differences of the dynamics in C, so no rows)
TREE_KERNELS = ("dynamics", "energy", "points", "jacobian")


def _tree_kernel(eom: EquationsOfMotion, name: str, folding: dict) -> ReducedKernel:
    """The assignments the kernel's results read (walked back from them), fixed parameters
    folded in. The recursion named its own intermediate terms, so there is no CSE pass: its
    operation count is that of the assignments it keeps."""
    tree = eom.tree
    if name == "dynamics":
        labelled = [(("UD", j, 0), e) for j, e in enumerate(tree.accelerations)] + \
            [(("D", j, 0), e) for j, e in enumerate(tree.pivots)] + \
            [(("DS", j, 0), e) for j, e in enumerate(tree.pivot_scales)]
    elif name == "energy":
        labelled = [(("E", 0, 0), tree.energy)]
    elif name == "points":
        labelled = [(("P", i, c), xyz[c]) for i, (_, xyz) in enumerate(tree.points) for c in range(3)]
    else:
        labelled = []
    needed = set()
    for _, expr in labelled:
        needed |= expr.free_symbols
    kept = []
    for symbol, expr in reversed(tree.assignments):
        if symbol in needed:
            kept.append((symbol, expr))
            needed |= expr.free_symbols
    kept.reverse()
    if folding:
        kept = [(s, e.xreplace(folding)) for s, e in kept]
        labelled = [(label, e.xreplace(folding)) for label, e in labelled]
    ops = count_operations([e for _, e in kept] + [e for _, e in labelled])
    return ReducedKernel(name=name, temporaries=tuple(kept), results=tuple(labelled), ops_before=ops, ops_after=ops)


def _reduce(name: str, labels: list, exprs: list, constants: Mapping | None = None) -> tuple:
    """The kernel of ``exprs`` after CSE and `factor_sums`, the ``constants`` (fixed parameter ->
    Float) folded in after them; and the operations that folding took out."""
    before = count_operations(exprs)
    replacements, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("cse_a"), order="canonical")
    replacements, reduced = _factored(replacements, reduced)
    after = count_operations([v for _, v in replacements] + list(reduced))
    # factoring leaves sums that several expressions now share (x + y taken out of two of them):
    # a second CSE finds those, and factoring again what it leaves (the Whipple bicycle's
    # dynamics kernel: 1441 operations after the first round, 1393 after the second)
    shared, rewritten = sp.cse([v for _, v in replacements] + list(reduced),
                               symbols=sp.numbered_symbols("cse_b"), order="canonical")
    if shared:
        n = len(replacements)
        merged = _in_order(shared + [(symbol, expr) for (symbol, _), expr in zip(replacements, rewritten[:n])],
                           rewritten[n:])
        again, again_reduced = _factored(merged, rewritten[n:])
        again_after = count_operations([v for _, v in again] + list(again_reduced))
        if again_after < after:
            replacements, reduced, after = again, again_reduced, again_after
    replacements, reduced = _numbered(*_without_copies(replacements, reduced), exprs)
    saved = 0
    if constants is not None:
        replacements, reduced = _fold_constants(name, replacements, reduced, constants)
        unfolded, after = after, count_operations([v for _, v in replacements] + list(reduced))
        saved = unfolded - after
    kernel = ReducedKernel(name=name, temporaries=tuple(replacements),
                           results=tuple(zip(labels, reduced)), ops_before=before, ops_after=after)
    return kernel, saved


#: digits of the values of folded terms (a double needs 17)
_DIGITS = 30


def _fold_constants(name: str, replacements: list, results: list, constants: Mapping) -> tuple:
    """``replacements`` and ``results`` with the fixed parameters' ``constants`` folded in: a
    temporary or result that reads nothing else becomes its value; in a sum or product, the terms
    or factors that read nothing else become one named constant (g*l*m*sin(q) -> fixed0*sin(q));
    the fixed parameters still read are defined first. A number never enters a sum's factor, so
    sympy has nothing to distribute. Returns (the temporaries, the results)."""
    values = dict(constants)
    taken = set(values)
    for symbol, expr in replacements:
        taken |= {symbol} | expr.free_symbols
    for expr in results:
        taken |= expr.free_symbols
    fresh = sp.numbered_symbols("fixed", exclude=taken)
    named: dict = {}
    definitions: list = []
    memo: dict = {}

    def is_constant(expr) -> bool:  # a number-valued term (conditions and Piecewise pairs are folded inside)
        return isinstance(expr, sp.Expr) and expr.free_symbols <= values.keys()

    def constant(expr):
        if expr.is_Number or expr in values:
            return expr
        if expr not in named:
            symbol = named[expr] = next(fresh)
            values[symbol] = _constant_value(name, expr, values)
            definitions.append((symbol, values[symbol]))
        return named[expr]

    def fold(expr):
        if expr.is_Atom or not expr.args:
            return expr
        known = memo.get(expr)
        if known is None:
            args = [constant(a) if is_constant(a) else fold(a) for a in expr.args]
            if expr.is_Add or expr.is_Mul:
                fixed = [a for a in args if is_constant(a)]
                if len(fixed) >= 2:
                    args = [constant(expr.func(*fixed))] + [a for a in args if not is_constant(a)]
            known = memo[expr] = expr.func(*args)
        return known

    folded = []
    for symbol, expr in replacements:
        if is_constant(expr):
            values[symbol] = _constant_value(name, expr, values)
            folded.append((symbol, values[symbol]))
        else:
            folded.append((symbol, fold(expr)))
    results = [_constant_value(name, expr, values) if is_constant(expr) else fold(expr) for expr in results]
    folded = _used([(p, value) for p, value in constants.items()] + definitions + folded, results)
    return folded, results


def _constant_value(name: str, expr, values: Mapping):
    """The number ``expr``, a term of fixed parameters and numbers only (pi, sqrt(2), cos(1) for a
    parameter fixed at 1), is at their ``values``; a condition of them (k > 1), true or false."""
    if not isinstance(expr, sp.Expr):  # a Boolean (a Symbol is both)
        value = expr.xreplace(values)
        if value in (sp.true, sp.false):
            return value
        raise KernelError(f"kernel {name!r}: its condition {expr} of fixed parameters only is {value} at their values")
    value = expr.xreplace(values).evalf(_DIGITS)
    if not (value.is_Number and value.is_finite and value.is_real):
        raise KernelError(f"kernel {name!r}: its term {expr} of fixed parameters only is "
                          f"{value} at their values; fix them to other values, or leave them free")
    return value


def _factored(replacements: list, results: list) -> tuple:
    """`factor_sums` over temporaries and results, then only the temporaries still read."""
    memo: dict = {}
    replacements = [(symbol, factor_sums(expr, memo)) for symbol, expr in replacements]
    results = [factor_sums(expr, memo) for expr in results]
    return _used(replacements, results), results


def _in_order(definitions: list, results: list) -> list:
    """``definitions`` (symbol, expr) ordered so that each comes after those it reads (in their
    given order otherwise), the ones the results read; iterative, as chains of them can be long."""
    defined = dict(definitions)
    placed: set = set()
    ordered = []
    roots = [symbol for symbol, _ in definitions] + \
        sorted({s for expr in results for s in expr.free_symbols if s in defined}, key=sp.default_sort_key)
    for root in roots:
        if root in placed:
            continue
        stack = [(root, False)]
        while stack:
            symbol, ready = stack.pop()
            if symbol in placed:
                continue
            if ready:
                placed.add(symbol)
                ordered.append((symbol, defined[symbol]))
                continue
            stack.append((symbol, True))
            reads = sorted((s for s in defined[symbol].free_symbols if s in defined and s not in placed),
                           key=sp.default_sort_key, reverse=True)
            stack.extend((s, False) for s in reads)
    return ordered


def _without_copies(replacements: list, results: list) -> tuple:
    """A temporary that only copies another symbol (tmp3 = tmp0: a second CSE round can leave one
    when factoring reduced a temporary to another) replaced by that symbol wherever it is read."""
    copies = {symbol: expr for symbol, expr in replacements if expr.is_Symbol}
    if not copies:
        return replacements, results
    for symbol, expr in copies.items():  # chains: tmp5 = tmp3 = tmp0
        while expr in copies:
            expr = copies[expr]
        copies[symbol] = expr
    return ([(symbol, expr.xreplace(copies)) for symbol, expr in replacements if symbol not in copies],
            [expr.xreplace(copies) for expr in results])


def _numbered(replacements: list, results: list, exprs: list) -> tuple:
    """The temporaries renamed tmp0, tmp1, ... in evaluation order (clear of the inputs' names)."""
    inputs = free_symbols_of(sp.sympify(e) for e in exprs)
    names = sp.numbered_symbols("tmp", exclude=inputs)
    renamed = {symbol: next(names) for symbol, _ in replacements}
    return ([(renamed[symbol], expr.xreplace(renamed)) for symbol, expr in replacements],
            [expr.xreplace(renamed) for expr in results])


def _used(replacements: list, results: list) -> list:
    """The temporaries the results read, directly or through others (factoring can cancel terms:
    a*(x - y) + a*(y + z) -> a*(x + z) no longer reads y)."""
    needed = set()
    for expr in results:
        needed |= expr.free_symbols
    kept = []
    for symbol, expr in reversed(replacements):
        if symbol in needed:
            kept.append((symbol, expr))
            needed |= expr.free_symbols
    return kept[::-1]


def factor_sums(expr, memo: dict):
    """``expr`` with the factors its sums' terms share pulled out, greedily: in every sum, the
    factor most terms hold (ties: sympy's sort order) is taken out of those terms, and the inner
    and the remaining sums are factored the same way; a*x + a*y + b*x -> a*(x + y) + b*x. CSE
    leaves such sums (it shares subexpressions, not factors): the Whipple bicycle's dynamics
    kernel took 1525 operations after CSE, 1441 after this (2026-11-26)."""
    known = memo.get(expr)
    if known is not None:
        return known
    if expr.is_Atom or not expr.args:
        result = expr
    else:
        args = [factor_sums(a, memo) for a in expr.args]
        result = expr.func(*args) if any(a is not b for a, b in zip(args, expr.args)) else expr
        if result.is_Add:
            result = _factor_terms(list(result.args))
    memo[expr] = result
    return result


def _factor_terms(terms: list):
    products = []
    while len(terms) > 1:  # a loop, not recursion, over the factors taken out: sums can be long
        counts: dict = {}
        for term in terms:
            for factor in _factors(term):
                counts[factor] = counts.get(factor, 0) + 1
        most = max(counts.values(), default=0)
        if most < 2:
            break
        factor = min((f for f, c in counts.items() if c == most), key=sp.default_sort_key)
        inside = [term / factor for term in terms if factor in _factors(term)]
        terms = [term for term in terms if factor not in _factors(term)]
        products.append(sp.Mul(factor, _factor_terms(inside)))
    return sp.Add(*products, *terms)


def _factors(term) -> set:
    """The symbolic factors of a sum's term (numbers are not factored out: sympy distributes them)."""
    args = term.args if term.is_Mul else (term,)
    return {a for a in args if not a.is_Number}


def count_operations(exprs) -> int:
    """``sum(sympy.count_ops(e) for e in exprs)``, with each distinct subexpression counted once and
    reused: count_ops walks every occurrence of a repeated subtree (the expressions before CSE
    repeat many: it took 0.42 of the 0.80 s of reducing the Whipple bicycle's kernels). The rules
    are count_ops's own, node by node; tests/symbolic/test_operation_count.py checks the two agree."""
    memo: dict = {}
    total = 0
    for expr in exprs:
        expr = sp.sympify(expr)
        if _coeff_isneg is not None and isinstance(expr, sp.Expr) and not expr.is_Relational:
            try:
                total += _count(expr, memo)
                continue
            except RecursionError:
                pass
        total += int(sp.count_ops(expr))
    return total


def _count(a, memo: dict) -> int:
    known = memo.get(a)
    if known is None:
        known = memo[a] = _count_node(a, memo)
    return known


def _fraction(product):
    """sympy's fraction(product) of a Mul; (product, 1) without rebuilding it when no factor is a
    power, an exp or a non-integer rational (fraction's Mul(*factors) took most of the counting)."""
    if any(f.is_Pow or isinstance(f, sp.exp) or (f.is_Rational and not f.is_Integer) for f in product.args):
        return fraction(product)
    return product, sp.S.One


def _count_node(a, memo: dict) -> int:
    """The operations sympy.count_ops (visual=False) charges for node ``a`` and what it pushes."""
    ops = 0
    if a.is_Rational:
        return 0 if a is sp.S.One else (1 if a.p < 0 else 0) + (1 if a.q != 1 else 0)
    if a.is_Mul:
        if _coeff_isneg(a):
            ops += 1  # NEG
            a = a.as_two_terms()[1] if a.args[0] is sp.S.NegativeOne else -a
        n, d = _fraction(a)
        if n.is_Integer:
            return ops + 1 + (1 if n < 0 else 0) + _count(d, memo)  # DIV (and NEG)
        if d is not sp.S.One:
            return ops + 1 + (0 if d.is_Integer else _count(d, memo)) + _count(n, memo)
    elif a.is_Add:
        terms = a.args
        negative = [_coeff_isneg(t) for t in terms]
        ops += len(terms) - 1  # ADD or SUB between terms; a leading negative term is SUB - ADD = 0
        ops += sum(_count(-t if neg else t, memo) for t, neg in zip(terms, negative))
        return ops + (1 if all(negative) else 0)  # -x - y = NEG + SUB
    if a.is_Pow and a.exp is sp.S.NegativeOne:
        return ops + 1 + _count(a.base, memo)
    if a == sp.S.Exp1:
        return ops + 1
    if a.is_Pow and a.base == sp.S.Exp1:
        return ops + 1 + _count(a.exp, memo)
    if a.is_Mul or isinstance(a, LatticeOp):
        ops += len(a.args) - 1
    elif a.args and (a.is_Pow or a.is_Function or isinstance(a, (sp.Derivative, sp.Integral, sp.Sum))):
        ops += 1
    if not a.is_Symbol:
        ops += sum(_count(arg, memo) for arg in a.args)
    return ops
