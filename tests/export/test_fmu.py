"""FMU export (issue 16 item 3): the FMI 2.0 and 3.0 FMUs are valid, and FMPy runs them to our numbers.

Expected values and where they come from:
- validity: FMPy's own validation (schema, variable names, ModelStructure, start values);
- Co-Simulation: our `simulate` (the C driver loop of the compiled kernel, not the FMU's
  doStep) with the same method, step and parameters, to 1e-12; a remainder interval against
  `simulate` runs chained by hand (whole steps, then one short step);
- Model Exchange: FMPy's CVode against scipy's DOP853 at rtol = atol = 1e-12 on the double
  pendulum hand-derived from Landau & Lifshitz's Lagrangian (Mechanics, sec. 5, problem 1),
  written in numpy here, independent of the package;
- the FMI functions' signatures: the standard's own headers as FMPy ships them;
- the source build: FMPy's ``build_platform_binary`` (CMake), compared with the shipped binary.
Each FMU test runs for FMI 2.0 and FMI 3.0 (the `fmi_version` fixture).
"""
from __future__ import annotations

import doctest
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description, simulate_fmu  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

from lagcodegen import Model  # noqa: E402
from lagcodegen.catalog import double_pendulum  # noqa: E402
from lagcodegen.cli.commands import main  # noqa: E402
from lagcodegen.export import FmuError, export_fmu  # noqa: E402
from lagcodegen.export.variables import VariableError  # noqa: E402
from lagcodegen.pipeline import compile_model  # noqa: E402
from lagcodegen.run.simulate import simulate  # noqa: E402

pytestmark = pytest.mark.compiler

STATES = ("q1", "q2", "q1_d", "q2_d")
X0 = {"q1": 1.0, "q2": 0.5, "q1_d": 0.0, "q2_d": 0.0}
H = 1e-3


@pytest.fixture(scope="module")
def pendulum():
    return compile_model(double_pendulum(), methods=("rk4",))


@pytest.fixture(scope="module", params=["2.0", "3.0"])
def fmi_version(request):
    return request.param


@pytest.fixture(scope="module")
def pendulum_fmu(pendulum, fmi_version, tmp_path_factory):
    return export_fmu(pendulum, tmp_path_factory.mktemp("fmu") / "double_pendulum.fmu", x0=X0, step=H,
                      fmi_version=fmi_version)


@pytest.fixture(scope="module")
def oscillator(driven_oscillator):
    model = driven_oscillator(measurements={"spring_force": lambda x, F, m, k, c: k * x})
    return compile_model(model, methods=("rk4",))


@pytest.fixture(scope="module")
def oscillator_fmu(oscillator, fmi_version, tmp_path_factory):
    return export_fmu(oscillator, tmp_path_factory.mktemp("fmu") / "oscillator.fmu", x0={"x": 0.2}, step=H,
                      fmi_version=fmi_version)


def states(result, names=STATES) -> np.ndarray:
    return np.column_stack([result[name] for name in names])


def test_fmpy_validation_finds_no_problem(pendulum_fmu, oscillator_fmu, fmi_version):
    assert validate_fmu(str(pendulum_fmu)) == []
    assert validate_fmu(str(oscillator_fmu)) == []
    description = read_model_description(str(oscillator_fmu))
    assert description.fmiVersion == fmi_version
    kinds = {v.name: (v.causality, v.variability) for v in description.modelVariables}
    assert kinds["F"] == ("input", "continuous") and kinds["k"] == ("parameter", "tunable")
    assert kinds["spring_force"] == ("output", "continuous") and kinds["energy"] == ("output", "continuous")
    assert kinds["step_size"] == ("parameter", "fixed")
    assert [d.variable.name for d in description.derivatives] == ["der(x)", "der(x_d)"]


def test_co_simulation_equals_simulate(pendulum, pendulum_fmu):
    result = simulate_fmu(str(pendulum_fmu), stop_time=2.0, output_interval=0.01, output=[*STATES, "energy"])
    reference = simulate(pendulum, X0, 2.0, H, "rk4", stride=10, energy=True)  # our C driver loop
    np.testing.assert_allclose(result["time"], reference.t, rtol=0, atol=1e-12)
    assert np.max(np.abs(states(result) - reference.x)) <= 1e-12
    assert np.max(np.abs(result["energy"] - reference.energy)) <= 1e-12


def test_an_interval_of_two_and_a_half_steps_ends_with_a_short_step(pendulum, pendulum_fmu):
    result = simulate_fmu(str(pendulum_fmu), stop_time=0.01, output_interval=0.0025, output=list(STATES))
    x, expected = [X0[name] for name in STATES], []
    for _ in range(4):  # by hand: two steps of H, then one of H / 2 (the pendulum is autonomous)
        x = simulate(pendulum, x, 2 * H, H, "rk4").x[-1]
        x = simulate(pendulum, x, H / 2, H / 2, "rk4", check_stability=False).x[-1]
        expected.append(x)
    assert np.max(np.abs(states(result)[1:] - np.array(expected))) <= 1e-12


def test_start_values_set_parameters_and_states(pendulum, pendulum_fmu):
    changed = {"m2": 2.0, "l1": 0.7, "q1": 0.3, "q2_d": -0.4}
    result = simulate_fmu(str(pendulum_fmu), stop_time=1.0, output_interval=0.01, output=list(STATES),
                          start_values=changed)
    x0 = X0 | {"q1": 0.3, "q2_d": -0.4}
    reference = simulate(pendulum, x0, 1.0, H, "rk4", stride=10, params={"m2": 2.0, "l1": 0.7})
    assert np.max(np.abs(states(result) - reference.x)) <= 1e-12
    assert np.max(np.abs(states(result) - simulate(pendulum, x0, 1.0, H, "rk4", stride=10).x)) > 1e-3


def test_a_driven_model_follows_the_input_signal_held_over_each_interval(oscillator, oscillator_fmu):
    interval, stop = 0.01, 1.0
    knots = np.arange(101) * interval  # the communication points FMPy computes: start + k * interval
    values = np.sin(3 * knots) + 0.5
    signal = np.array(list(zip(knots, values)), dtype=[("time", np.float64), ("F", np.float64)])
    result = simulate_fmu(str(oscillator_fmu), stop_time=stop, output_interval=interval, input=signal,
                          output=["x", "x_d", "spring_force"])
    # FMPy sets F to the knot value at each communication point; the FMU holds it for 10 steps
    per_step = np.repeat(values[:-1], 10)
    reference = simulate(oscillator, {"x": 0.2}, stop, H, "rk4", stride=10, inputs=per_step)
    assert np.max(np.abs(states(result, ("x", "x_d")) - reference.x)) <= 1e-12
    assert np.max(np.abs(result["spring_force"] - reference["spring_force"])) <= 1e-12
    assert np.ptp(result["x"]) > 0.1  # the input moves it


def test_a_diverging_step_stops_the_run_and_says_why(pendulum_fmu):
    messages = []
    with pytest.raises(Exception, match="DoStep failed with status 3"):  # fmi2Error = fmi3Error = 3
        simulate_fmu(str(pendulum_fmu), stop_time=50.0, output_interval=1.0,
                     start_values={"step_size": 0.9, "q1_d": 20.0}, logger=lambda *args: messages.append(repr(args)))
    # the status message of the C kernel (status.py's NONFINITE_STATE), with the step's start time
    assert any("DoStep: the step (t = 1): the state or its derivatives became NaN or infinite" in m for m in messages)


def landau_rhs(t, x, m1=1.0, m2=1.0, l1=1.0, l2=1.0, g=9.81):
    """The double pendulum in absolute angles from the downward vertical, from
    L = (m1 + m2)/2 l1^2 q1d^2 + m2/2 l2^2 q2d^2 + m2 l1 l2 q1d q2d cos(q1 - q2)
        + (m1 + m2) g l1 cos q1 + m2 g l2 cos q2 (Landau & Lifshitz, Mechanics, sec. 5, problem 1)."""
    q1, q2, u1, u2 = x
    c, s = np.cos(q1 - q2), np.sin(q1 - q2)
    M = np.array([[(m1 + m2) * l1 ** 2, m2 * l1 * l2 * c], [m2 * l1 * l2 * c, m2 * l2 ** 2]])
    F = np.array([-m2 * l1 * l2 * u2 ** 2 * s - (m1 + m2) * g * l1 * np.sin(q1),
                  m2 * l1 * l2 * u1 ** 2 * s - m2 * g * l2 * np.sin(q2)])
    return np.concatenate([[u1, u2], np.linalg.solve(M, F)])


def test_model_exchange_under_cvode_equals_dop853(pendulum_fmu):
    from scipy.integrate import solve_ivp

    result = simulate_fmu(str(pendulum_fmu), fmi_type="ModelExchange", stop_time=2.0, output_interval=0.01,
                          relative_tolerance=1e-10, output=list(STATES))  # CVode: atol = rtol * nominal (1)
    t = np.asarray(result["time"])
    reference = solve_ivp(landau_rhs, (0.0, 2.0), [X0[name] for name in STATES], method="DOP853",
                          t_eval=t, rtol=1e-12, atol=1e-12).y.T
    # CVode's global error at rtol = atol = 1e-10 over 2 s: measured 3.4e-8 (6.7e-7 at 1e-8)
    assert np.max(np.abs(states(result) - reference)) <= 1e-6


def test_the_fmi_functions_match_the_standard_headers(pendulum_fmu, fmi_version, tmp_path, require_tool):
    """Compile the wrapper against the FMI headers FMPy ships: any signature that differs from the
    standard's declaration is a conflicting-types error, a missing function a missing symbol."""
    gcc = require_tool("gcc")
    with zipfile.ZipFile(pendulum_fmu) as archive:
        archive.extractall(tmp_path)
    headers = Path(fmpy.__file__).parent / "c-code"
    sources = sorted(str(p) for p in (tmp_path / "sources").glob("*.c"))
    macro = f"-DLCG_FMI{fmi_version[0]}_STANDARD_HEADERS"
    run = subprocess.run([gcc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", macro,
                          "-I", str(headers), "-I", str(tmp_path / "sources"), "-fPIC", "-shared", *sources,
                          "-o", str(tmp_path / "check.so"), "-lm"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    # every function the standard declares is defined (its header lists them as #define fmiNName)
    header = (headers / f"fmi{fmi_version[0]}Functions.h").read_text()
    declared = set(re.findall(rf"#define (fmi{fmi_version[0]}[A-Z]\w*)\s+fmi{fmi_version[0]}FullName", header))
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(tmp_path / "check.so")], capture_output=True,
                             text=True).stdout.split()
    assert len(declared) > 40 and declared <= set(symbols), declared - set(symbols)


def test_the_fmu_builds_from_its_sources(pendulum_fmu, tmp_path, require_tool):
    require_tool("cmake")
    from fmpy.build import build_platform_binary

    with zipfile.ZipFile(pendulum_fmu) as archive:
        archive.extractall(tmp_path / "fmu")
    shutil.rmtree(tmp_path / "fmu" / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(tmp_path / "fmu", build_dir=tmp_path / "build")
    rebuilt = simulate_fmu(str(tmp_path / "fmu"), stop_time=1.0, output_interval=0.01, output=list(STATES))
    shipped = simulate_fmu(str(pendulum_fmu), stop_time=1.0, output_interval=0.01, output=list(STATES))
    assert np.max(np.abs(states(rebuilt) - states(shipped))) <= 1e-12


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_the_cli_writes_an_fmu_fmpy_reads(tmp_path, capsys, version):
    out = tmp_path / "x.fmu"
    assert main(["fmu", "double_pendulum", "--out", str(out), "--x0", "q1=1", "--no-binary",
                 "--fmi-version", version, "--fixed", "g=9.81"]) == 0
    assert "wrote" in capsys.readouterr().out
    description = read_model_description(str(out))
    assert description.coSimulation.modelIdentifier == "lcg_double_pendulum" and description.modelExchange
    assert description.fmiVersion == version and validate_fmu(str(out)) == []
    variables = {v.name: v for v in description.modelVariables}
    assert variables["q1"].start == "1.0" and variables["m1"].variability == "tunable"
    assert (variables["g"].causality, variables["g"].variability, variables["g"].start) == ("local", "constant", "9.81")


def test_the_docstring_example_runs():
    from lagcodegen.export import fmu

    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in doctest.DocTestFinder(recurse=False).find(fmu.export_fmu, "export_fmu"):
        runner.run(test)
    assert runner.tries and runner.failures == 0


# -- bad input ----------------------------------------------------------------------------------
def test_an_output_path_that_is_a_directory_is_named(pendulum, tmp_path):
    with pytest.raises(FmuError, match=f"FMU path '{tmp_path}' is a directory"):
        export_fmu(pendulum, tmp_path)
    with pytest.raises(FmuError, match="its folder .*missing.* does not exist"):
        export_fmu(pendulum, tmp_path / "missing" / "x.fmu")


def test_a_parameter_without_a_value_is_named(tmp_path):
    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    model = Model("spring", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  parameter_values={"m": 1.0})
    with pytest.raises(FmuError, match=r"parameter\(s\) 'k' of 'spring' have no value, and an FMI parameter needs a "
                                       r"constant start value"):
        export_fmu(model, tmp_path / "spring.fmu", binary=False)


def test_bad_start_values_and_methods_are_named(pendulum, tmp_path):
    with pytest.raises(FmuError, match="'theta' is not a free parameter of 'double_pendulum'"):
        export_fmu(pendulum, tmp_path / "a.fmu", params={"theta": 1.0})
    with pytest.raises(FmuError, match=r"x0\['q1'\] must be a finite real number"):
        export_fmu(pendulum, tmp_path / "a.fmu", x0={"q1": float("nan")})
    with pytest.raises(FmuError, match="x0: 'q3' is not a state of 'double_pendulum'"):
        export_fmu(pendulum, tmp_path / "a.fmu", x0={"q3": 1.0})
    with pytest.raises(FmuError, match="method 'symplectic_euler' is not compiled into 'double_pendulum'"):
        export_fmu(pendulum, tmp_path / "a.fmu", method="symplectic_euler")
    with pytest.raises(FmuError, match="step must be a positive finite number, got 0"):
        export_fmu(pendulum, tmp_path / "a.fmu", step=0)
    assert not list(tmp_path.iterdir())


def test_a_variable_name_taken_twice_is_named(driven_oscillator, tmp_path):
    model = driven_oscillator("clash", measurements={"energy": lambda x, F, m, k, c: k * x ** 2 / 2})
    with pytest.raises(VariableError, match="'energy' is taken twice: by the energy and by the measurement"):
        export_fmu(model, tmp_path / "a.fmu", binary=False)


def test_the_cli_names_an_unknown_model_and_a_directory(tmp_path, capsys):
    assert main(["fmu", "no_such_model", "--out", str(tmp_path / "x.fmu")]) == 2
    assert "model 'no_such_model' is neither an example" in capsys.readouterr().err
    assert main(["fmu", "double_pendulum", "--out", str(tmp_path)]) == 2
    # found by review: any name was taken, the model's own .py file replaced by the archive
    source = tmp_path / "model.py"
    source.write_text("model = None\n")
    assert main(["fmu", "double_pendulum", "--out", str(source), "--no-binary"]) == 2
    assert source.read_text() == "model = None\n"
    assert f"FMU path '{tmp_path}' is a directory" in capsys.readouterr().err


@pytest.fixture(scope="module")
def polar_fmu(fmi_version, tmp_path_factory):
    """`catalog.elastic_pendulum` with k = g = 0: a free particle in polar coordinates, M = diag(m,
    m r^2). From r = 1.0005, r' = -1, phi' = 0 it moves on a straight line through the pivot, r(t) =
    1.0005 - t exactly (phi'' = -2 r' phi' / r = 0; tests/numeric/test_singular_crossing.py), so the
    grid state at t = 1.00 is r = 0.0005, next to the singular r = 0 (the pivot m r^2 drops 441x in
    that step), and the next steps jump across it."""
    from lagcodegen.catalog import elastic_pendulum

    system = compile_model(elastic_pendulum(), methods=("rk4",))
    return export_fmu(system, tmp_path_factory.mktemp("fmu") / "polar.fmu",
                      x0={"r": 1.0005, "phi": 0.3, "r_d": -1.0, "phi_d": 0.0}, params={"k": 0.0, "g": 0.0},
                      step=0.01, fmi_version=fmi_version)


@pytest.mark.parametrize("stop_time, interval", [(2.0, 0.01), (2.0, 0.25), (1.0, 0.5), (1.0, 1.0)])
def test_co_simulation_stops_where_a_step_lands_next_to_a_singular_configuration(polar_fmu, stop_time, interval):
    """doStep runs the singularity monitor of `simulate`, with its history kept from one doStep to
    the next, and judges the last step of each doStep (a landing in the last step of the run, stop
    time 1.0, included): a step across the polar origin never ends with status OK. The singular
    step is the one to t = 1.00; the monitor reports it from that state, as simulate does
    (failed_time 1.0)."""
    messages = []
    with pytest.raises(Exception, match="DoStep failed with status 3"):
        simulate_fmu(str(polar_fmu), stop_time=stop_time, output_interval=interval, output=["r"],
                     logger=lambda *args: messages.append(repr(args)))
    assert any("the mass matrix is singular" in m and "(t = 1)" in m for m in messages), messages[-3:]


def test_a_failed_step_leaves_the_last_accepted_state(polar_fmu, fmi_version):
    """Intervals of 0.3 s: the monitor rejects the step from t = 1.00 (r = 0.0005, next to the
    origin) in the middle of the fourth doStep. The FMU's state stays the one the failed step
    started from, r = 1.0005 - 1.00 = 0.0005 (the exact line, above), not the state past the
    origin the rejected step reached (r = -0.0095)."""
    from fmpy import extract
    from fmpy.simulation import instantiate_fmu

    description = read_model_description(str(polar_fmu))
    refs = {v.name: v.valueReference for v in description.modelVariables}
    messages = []

    def logger(*args):  # a logger of our own: FMPy's message proxy keeps the last one it was given
        messages.append(repr(args))

    slave = instantiate_fmu(extract(str(polar_fmu)), description, fmi_type="CoSimulation", logger=logger)
    if fmi_version == "2.0":
        slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    t = 0.0
    with pytest.raises(Exception, match="DoStep failed"):
        for _ in range(8):
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=0.3)
            t += 0.3
    assert t == pytest.approx(0.9)
    assert any("(t = 1)" in m for m in messages), messages
    read = slave.getReal if fmi_version == "2.0" else slave.getFloat64
    assert read([refs["r"]])[0] == pytest.approx(0.0005, abs=1e-12)
    slave.freeInstance()


def refused_set_messages(pendulum_fmu, fmi_version, name, value, initializing):
    """The log of a Co-Simulation pendulum whose setter refuses ``name = value`` (while initializing,
    or between two doSteps)."""
    from fmpy import extract
    from fmpy.simulation import instantiate_fmu

    description = read_model_description(str(pendulum_fmu))
    ref = next(v.valueReference for v in description.modelVariables if v.name == name)
    messages = []

    def logger(*args):  # a logger of our own (see test_a_failed_step_leaves_the_last_accepted_state)
        messages.append(repr(args))

    fmu = instantiate_fmu(extract(str(pendulum_fmu)), description, fmi_type="CoSimulation", logger=logger)
    set_value = fmu.setReal if fmi_version == "2.0" else fmu.setFloat64
    if fmi_version == "2.0":
        fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    if not initializing:
        fmu.exitInitializationMode()
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
    with pytest.raises(Exception, match="Set"):
        set_value([ref], [value])
    fmu.freeInstance()
    return ref, messages


@pytest.mark.parametrize("name, value", [("m1", float("nan")), ("l2", float("inf")), ("q1", float("nan"))])
def test_a_state_or_parameter_that_is_not_finite_is_refused_by_value_reference(pendulum_fmu, fmi_version, name,
                                                                               value):
    """A parameter set to NaN between two doSteps used to be taken, and the next step stopped with
    'the mass matrix is singular', which names neither the variable nor the value; a state set to
    NaN during initialization likewise. The setter now refuses it and names the value reference."""
    # states may be set only while initializing
    ref, messages = refused_set_messages(pendulum_fmu, fmi_version, name, value, initializing=name.startswith("q"))
    assert any(f"value reference {ref} (a state, parameter, input or the step size) cannot be set to" in m
               and "not finite" in m for m in messages), messages


@pytest.mark.parametrize("name, value, reason", [
    # found by review: a NaN input was taken and reported later as a diverged state, naming no input
    ("F", float("nan"), "(a state, parameter, input or the step size) cannot be set to nan: not finite"),
    ("F", float("inf"), "(a state, parameter, input or the step size) cannot be set to inf: not finite"),
    ("step_size", 0.0, "(the step size) cannot be set to 0: not positive"),
])
def test_an_input_or_step_that_is_not_finite_is_refused_by_value_reference(oscillator_fmu, fmi_version, name,
                                                                           value, reason):
    ref, messages = refused_set_messages(oscillator_fmu, fmi_version, name, value, initializing=True)
    assert any(f"value reference {ref} {reason}" in m for m in messages), messages


def test_a_state_set_after_initialization_is_refused_as_not_settable(pendulum_fmu, fmi_version):
    """A finite state set between two doSteps: refused with the setter's other reason (FMI: states of a
    Co-Simulation FMU are set only while initializing)."""
    _, messages = refused_set_messages(pendulum_fmu, fmi_version, "q1", 0.5, initializing=False)
    assert any("not settable in this mode" in m for m in messages), messages


@pytest.mark.parametrize("start, point, size, reason", [
    # found by review: a NaN start time or communication point was taken (doSteps returned OK and took
    # no step, or the FMU's time became NaN); an infinite step size never returned
    (float("nan"), None, None, "the start time is not finite"),
    (0.0, float("nan"), H, "the communication point nan is not the FMU's time 0"),
    (0.0, 0.0, float("inf"), "the communication step size inf is not a finite non-negative number"),
    (0.0, 0.0, float("nan"), "the communication step size nan is not a finite non-negative number"),
    (0.0, 0.0, -H, "the communication step size -0.001 is not a finite non-negative number"),
])
def test_a_time_or_step_that_is_not_finite_is_refused(pendulum_fmu, fmi_version, start, point, size, reason):
    from fmpy import extract
    from fmpy.simulation import instantiate_fmu

    description = read_model_description(str(pendulum_fmu))
    messages = []

    def logger(*args):  # a logger of our own (see test_a_failed_step_leaves_the_last_accepted_state)
        messages.append(repr(args))

    fmu = instantiate_fmu(extract(str(pendulum_fmu)), description, fmi_type="CoSimulation", logger=logger)
    with pytest.raises(Exception, match="SetupExperiment|EnterInitializationMode|DoStep"):
        if fmi_version == "2.0":
            fmu.setupExperiment(startTime=start)
            fmu.enterInitializationMode()
        else:
            fmu.enterInitializationMode(startTime=start)
        fmu.exitInitializationMode()
        fmu.doStep(currentCommunicationPoint=point, communicationStepSize=size)
    fmu.freeInstance()
    assert any(reason in m for m in messages), messages


@pytest.fixture(scope="module")
def four_bar_system():
    from lagcodegen import catalog

    return compile_model(catalog.four_bar(), methods=("rk4",))


def closure_gap(result) -> float:
    """max | |B - O4| - l3 | of the catalog four-bar (O4 = (0.4, 0), l3 = 0.3): its loop closure, by hand."""
    return float(np.abs(np.hypot(result["B.x"] - 0.4, result["B.y"]) - 0.3).max())


@pytest.mark.parametrize("start, step, stop, warned", [
    # found by review: the FMU ran a constrained model off its constraints with OK and no word, where
    # simulate warns (ConstraintDriftWarning); now fmi2Warning/fmi3Warning with the offset, once
    ("off", 1e-4, 0.01, "ExitInitializationMode"),
    ("on", 1e-3, 1.0, "DoStep"),  # RK4 at h = 1e-3 drifts (simulate warns too)
    ("on", 1e-4, 0.01, None),
    # found by review (session 16): CVode at its default rtol carried the loop 0.28 m open, OK, no word
    ("model exchange", None, 1.0, "CompletedIntegratorStep"),
])
def test_a_constrained_fmu_warns_once_when_its_state_is_off_the_constraints(four_bar_system, fmi_version, tmp_path,
                                                                           start, step, stop, warned):
    from lagcodegen import catalog

    x0 = {"theta1": 0.3, "theta2": 0.0, "theta3": 0.0} if start == "off" else catalog.four_bar_state(0.3, 1.0)
    fmu = export_fmu(four_bar_system, tmp_path / "four_bar.fmu", x0=x0, step=step or 1e-3, fmi_version=fmi_version)
    messages = []
    interface = {"fmi_type": "ModelExchange"} if start == "model exchange" else {}
    result = simulate_fmu(str(fmu), stop_time=stop, output_interval=stop / 10, output=["B.x", "B.y"],
                          logger=lambda *args: messages.append(repr(args)), **interface)
    warnings = [m for m in messages if "is off constraint" in m]
    if warned is None:
        assert not warnings and closure_gap(result) < 1e-6
    else:
        assert len(warnings) == 1 and warned in warnings[0], messages
        assert closure_gap(result) > 1e-6


# --- found by the review of session 12 ---------------------------------------------------------------

def _cs_instance(fmu_path, fmi_version, start: float, messages: list, step_size: float | None = None):
    """A Co-Simulation instance of ``fmu_path`` initialized at ``start`` (step_size set while
    initializing when given), and the function reading values by name."""
    from fmpy import extract
    from fmpy.simulation import instantiate_fmu

    description = read_model_description(str(fmu_path))
    refs = {v.name: v.valueReference for v in description.modelVariables}
    fmu = instantiate_fmu(extract(str(fmu_path)), description, fmi_type="CoSimulation",
                          logger=lambda *args: messages.append(repr(args)))
    if fmi_version == "2.0":
        fmu.setupExperiment(startTime=start)
        fmu.enterInitializationMode()
    else:
        fmu.enterInitializationMode(startTime=start)
    if step_size is not None:
        (fmu.setReal if fmi_version == "2.0" else fmu.setFloat64)([refs["step_size"]], [step_size])
    fmu.exitInitializationMode()
    get = fmu.getReal if fmi_version == "2.0" else fmu.getFloat64
    return fmu, lambda names: np.array(get([refs[name] for name in names]))


def test_only_the_fmi_functions_are_exported(pendulum_fmu, fmi_version):
    """Found by review: the binary exported its kernel (lcg_double_pendulum_*), and its own calls went
    through the dynamic symbol table, so a host that had loaded another FMU of the same model with
    RTLD_GLOBAL (fixed g = 1.62) ran that one's kernel: q1(1) = 0.1631 instead of -0.3201, status OK."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) is not installed")
    with zipfile.ZipFile(pendulum_fmu) as archive:
        binary = next(name for name in archive.namelist() if name.startswith("binaries/"))
        data = archive.read(binary)
    path = Path(pendulum_fmu).with_suffix(".so")
    path.write_bytes(data)
    listing = subprocess.run([nm, "-D", "--defined-only", str(path)], capture_output=True, text=True, check=True)
    exported = [line.split()[-1] for line in listing.stdout.splitlines() if line.split()[1] in "TDBR"]
    prefix = "fmi2" if fmi_version == "2.0" else "fmi3"
    assert exported and all(name.startswith(prefix) for name in exported), exported


@pytest.mark.parametrize("start", [100.0, 1e5])
def test_a_master_on_its_own_time_grid_far_from_zero_is_followed(pendulum, pendulum_fmu, fmi_version, start):
    """Found by review: a master passing t0 + k dt (start 1e5, dt 1e-3) was refused at k = 2, "the
    communication point is not the FMU's time": they differ by a rounding unit of t, and the
    tolerance was 1e-9 of the step. The pendulum is autonomous, so 20 doSteps equal simulate's 20
    RK4 steps from 0 (the reference)."""
    messages: list = []
    fmu, read = _cs_instance(pendulum_fmu, fmi_version, start, messages)
    for k in range(20):
        fmu.doStep(currentCommunicationPoint=start + k * H, communicationStepSize=H)
    got = read(STATES)
    fmu.freeInstance()
    x0 = [X0[name] for name in STATES]
    want = simulate(pendulum, x0, t_end=20 * H, h=H).x[-1]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_a_huge_step_size_does_not_freeze_short_communication_steps(pendulum, pendulum_fmu, fmi_version):
    """Found by review: with step_size 1e10, a doStep over 0.05 counted as "nothing to integrate" (the
    slack was 1e-9 of the step) and returned OK with the state unchanged. Now each doStep takes one
    step of its interval: simulate with h = 0.05 is the reference."""
    messages: list = []
    fmu, read = _cs_instance(pendulum_fmu, fmi_version, 0.0, messages, step_size=1e10)
    for k in range(4):
        fmu.doStep(currentCommunicationPoint=k * 0.05, communicationStepSize=0.05)
    got = read(STATES)
    fmu.freeInstance()
    want = simulate(pendulum, [X0[name] for name in STATES], t_end=0.2, h=0.05).x[-1]
    assert abs(got[0] - X0["q1"]) > 0.05
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_a_do_step_of_more_than_1e8_steps_is_refused(pendulum_fmu, fmi_version):
    """Found by review: a doStep over 1e12 s (1e15 RK4 steps) never returned."""
    messages: list = []
    fmu, _ = _cs_instance(pendulum_fmu, fmi_version, 0.0, messages)
    with pytest.raises(Exception, match="DoStep"):
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e12)
    fmu.freeInstance()
    assert any("fixed steps of step_size" in m and "more than 1e+08" in m for m in messages), messages


def test_model_exchange_refuses_a_time_or_state_that_is_not_finite(pendulum_fmu, fmi_version):
    """Found by review: fmi2SetTime(NaN) and SetContinuousStates([NaN, ...]) returned OK, and the
    outputs read NaN with status OK."""
    from fmpy import extract
    from fmpy.simulation import instantiate_fmu

    description = read_model_description(str(pendulum_fmu))
    messages: list = []
    fmu = instantiate_fmu(extract(str(pendulum_fmu)), description, fmi_type="ModelExchange",
                          logger=lambda *args: messages.append(repr(args)))
    if fmi_version == "2.0":
        fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    if fmi_version == "2.0":
        fmu.enterContinuousTimeMode()
    with pytest.raises(Exception, match="SetTime"):
        fmu.setTime(float("nan"))
    with pytest.raises(Exception, match="SetContinuousStates"):
        import ctypes

        fmu.setContinuousStates((ctypes.c_double * 4)(1.0, float("nan"), 0.0, 0.0), 4)
    fmu.freeInstance()
    assert any("the time is not finite" in m for m in messages), messages
    assert any("state 1 (value reference 1) is not finite" in m for m in messages), messages


def test_a_compiled_model_without_its_points_is_refused_by_name(tmp_path, fmi_version):
    """Found by review: compiled with outputs=("rhs", "energy"), the FMU's wrapper called the missing
    points function (a gcc error; with binary=False a valid-looking FMU whose sources do not build)."""
    system = compile_model(double_pendulum(), outputs=("rhs", "energy"), methods=("rk4",))
    for binary in (True, False):
        with pytest.raises(FmuError, match=r"without its 'points' output.*outputs=\(\.\.\., 'points'\)"):
            export_fmu(system, tmp_path / "pendulum.fmu", binary=binary, fmi_version=fmi_version)


def test_the_fmu_file_is_written_like_any_new_file_and_never_over_a_device(pendulum, tmp_path, fmi_version):
    """Found by review: the FMU was mode 0600 under umask 022 (mkstemp's mode), an existing FIFO or
    device at the path (/dev/null) was replaced by a regular file, and a write error named the
    temporary file, not the path asked for."""
    import os
    import stat

    saved = os.umask(0o022)
    try:
        fmu = export_fmu(pendulum, tmp_path / "pendulum.fmu", binary=False, fmi_version=fmi_version)
    finally:
        os.umask(saved)
    assert stat.S_IMODE(fmu.stat().st_mode) == 0o644
    fifo = tmp_path / "pipe.fmu"
    os.mkfifo(fifo)
    with pytest.raises(FmuError, match="exists and is not a regular file"):
        export_fmu(pendulum, fifo, binary=False, fmi_version=fmi_version)
    assert stat.S_ISFIFO(fifo.stat().st_mode)
    with pytest.raises(FmuError, match=r"cannot write the FMU '/proc/lagcodegen\.fmu'"):
        export_fmu(pendulum, "/proc/lagcodegen.fmu", binary=False, fmi_version=fmi_version)


def test_a_start_off_a_velocity_constraint_is_warned(tmp_path, fmi_version):
    """Found by review: the FMU's drift check read the position constraints only, so a sleigh
    sliding sideways at the start ran with OK and no word (simulate warns). By hand, its blade
    constraint -x' sin(theta) + y' cos(theta) is -sin(0.5) = -0.479 at x' = 1, y' = 0, theta = 0.5."""
    x, y, theta = me.dynamicsymbols("x y theta")
    m, inertia, a = sp.symbols("m I a", positive=True)
    t = me.dynamicsymbols._t
    xc, yc = x + a * sp.cos(theta), y + a * sp.sin(theta)
    kinetic = m * (xc.diff(t) ** 2 + yc.diff(t) ** 2) / 2 + inertia * theta.diff(t) ** 2 / 2
    blade = -x.diff(t) * sp.sin(theta) + y.diff(t) * sp.cos(theta)
    model = Model("sleigh", [x, y, theta], [m, inertia, a], kinetic_energy=kinetic, motion_constraints=[blade],
                  parameter_values={m: 2.0, inertia: 0.3, a: 0.4})
    fmu = export_fmu(model, tmp_path / "sleigh.fmu", x0={"theta": 0.5, "x_d": 1.0}, step=1e-3, fmi_version=fmi_version)
    messages: list = []
    simulate_fmu(str(fmu), stop_time=0.01, logger=lambda *args: messages.append(repr(args)))
    warnings = [m for m in messages if "is off constraint 0 by |A u + dphi/dt| = 0.479" in m]
    assert len(warnings) == 1 and "ExitInitializationMode" in warnings[0], messages


# --- found by the review of session 16 ---------------------------------------------------------------

def test_model_exchange_functions_are_refused_on_a_co_simulation_instance(pendulum_fmu, fmi_version):
    """Were: SetTime(5) and SetContinuousStates on a Co-Simulation instance returned OK, and the next
    doStep(5, 0.01) integrated 4.91 s. Now an error (status 3) naming the function. FMPy's slave
    classes do not offer them: called through the library."""
    import ctypes

    messages: list = []
    prefix = "fmi2" if fmi_version == "2.0" else "fmi3"
    for name, arguments in (("SetContinuousStates", ((ctypes.c_double * 4)(0.0, 0.0, 0.0, 0.0), ctypes.c_size_t(4))),
                            ("SetTime", (ctypes.c_double(5.0),))):
        fmu, read = _cs_instance(pendulum_fmu, fmi_version, 0.0, messages)
        function = getattr(fmu.dll, prefix + name)
        function.restype = ctypes.c_int
        assert function(ctypes.c_void_p(fmu.component), *arguments) == 3
        fmu.freeInstance()
    assert sum("a Model Exchange function, called on a Co-Simulation instance" in m for m in messages) == 2, messages


def test_the_time_after_a_failed_step_is_the_state_s(polar_fmu, fmi_version):
    """Was: after the doStep from 0.9 failed at t = 1.00 (r = 1.0005 - t = 0.0005 kept, the exact line),
    fmi2LastSuccessfulTime and FMI 3's time still said 0.9."""
    messages: list = []
    fmu, read = _cs_instance(polar_fmu, fmi_version, 0.0, messages)
    t = 0.0
    with pytest.raises(Exception, match="DoStep failed"):
        for _ in range(8):
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=0.3)
            t += 0.3
    assert read(["r"])[0] == pytest.approx(0.0005, abs=1e-12)
    if fmi_version == "2.0":
        import ctypes

        from fmpy.fmi2 import fmi2LastSuccessfulTime

        last = ctypes.c_double()
        fmu.fmi2GetRealStatus(fmu.component, fmi2LastSuccessfulTime, ctypes.byref(last))
        assert last.value == pytest.approx(1.0, abs=1e-12)
    else:
        assert read(["time"])[0] == pytest.approx(1.0, abs=1e-12)
    fmu.freeInstance()


def test_an_output_undefined_at_a_finite_state_is_warned(driven_oscillator, fmi_version, tmp_path):
    """Was: a measurement sqrt(x) read NaN with OK and nothing logged, where simulate warns. From
    x = 0.5 at rest with F = 0: x = cos(2 t) / 2 by hand, negative from t = pi/4."""
    model = driven_oscillator("fmu_root", measurements={"root": lambda x, F, m, k, c: sp.sqrt(x)})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path / "cache")
    fmu = export_fmu(system, tmp_path / "root.fmu", x0={"x": 0.5}, step=1e-3, fmi_version=fmi_version)
    messages: list = []
    result = simulate_fmu(str(fmu), stop_time=1.0, output_interval=0.01, output=["root"], start_values={"F": 0.0},
                          logger=lambda *args: messages.append(repr(args)))
    assert np.isnan(result["root"][-1]) and not np.isnan(result["root"][0])
    assert any("is NaN or infinite at a finite state" in m for m in messages), messages


def test_a_model_exchange_error_speaks_of_the_state_not_of_steps(pendulum_fmu, fmi_version):
    """Was: with l2 = 0 (by hand the mass matrix loses rank: the second bob's inertia m2 l2^2 = 0), the
    derivatives' error said "a step changed its pivots ... a smaller h tells", where no step is taken."""
    messages: list = []
    with pytest.raises(Exception, match="GetDerivatives|right-hand side"):
        simulate_fmu(str(pendulum_fmu), stop_time=0.1, fmi_type="ModelExchange", start_values={"l2": 0.0},
                     logger=lambda *args: messages.append(repr(args)))
    derivative_errors = [m for m in messages if "Derivatives" in m]
    assert derivative_errors and all("at this state with these parameter values" in m and "smaller h" not in m
                                     for m in derivative_errors), messages
