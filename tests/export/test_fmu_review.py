"""The FMU found wrong by the review of session 14 (helper-44): against a hand RK4 step matrix, the FMI
standard's own text on modes and memory functions, and XML 1.0's character set."""
from __future__ import annotations

import ctypes
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

pytest.importorskip("fmpy")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.simulation import instantiate_fmu  # noqa: E402

from lagcodegen import Model  # noqa: E402
from lagcodegen.catalog import double_pendulum  # noqa: E402
from lagcodegen.export import FmuError, export_fmu  # noqa: E402

pytestmark = pytest.mark.compiler

H = 1e-6


@pytest.fixture(scope="module")
def damped_oscillator_fmu(tmp_path_factory):
    """m x'' + c x' + k x = 0 (m = 2, k = 8, c = 0.3), RK4 at step_size 1e-6; by hand x' = A x with
    A = [[0, 1], [-4, -0.15]], so one RK4 step is the matrix R = I + Ah + (Ah)^2/2 + (Ah)^3/6 + (Ah)^4/24."""
    x = me.dynamicsymbols("x")
    m, k, c = sp.symbols("m k c", positive=True)
    model = Model("msd", [x], [m, k, c], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  dissipation=c * x.diff() ** 2 / 2, parameter_values={m: 2.0, k: 8.0, c: 0.3})
    return str(export_fmu(model, tmp_path_factory.mktemp("msd") / "msd.fmu", x0={"x": 1.0}, step=H))


def _rk4_matrix(h: float) -> np.ndarray:
    Ah = np.array([[0.0, 1.0], [-4.0, -0.15]]) * h
    return np.eye(2) + Ah + Ah @ Ah / 2 + Ah @ Ah @ Ah / 6 + Ah @ Ah @ Ah @ Ah / 24


def _steps_between(before: np.ndarray, after: np.ndarray) -> int:
    """How many hand RK4 steps take ``before`` nearest to ``after``."""
    R, y, best = _rk4_matrix(H), before.copy(), (np.inf, 0)
    for n in range(1, 200):
        y = R @ y
        best = min(best, (float(np.max(np.abs(y - after))), n))
    return best[1]


def _started(path: str, start: float, logger=None):
    description = read_model_description(path)
    fmu = instantiate_fmu(extract(path), description, fmi_type="CoSimulation", logger=logger)
    fmu.setupExperiment(startTime=start)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    return fmu, {v.name: v.valueReference for v in description.modelVariables}


def test_a_do_step_far_from_zero_takes_the_steps_its_interval_holds(damped_oscillator_fmu):
    """Was: 105, 100, 101, 99, ... RK4 steps for doSteps of 1e-4 at step_size 1e-6 from t = 1.7e9 (a
    time slack of 16 eps |t| = 6e-6, six steps, decided whether a step fit): the state returned was
    up to 5 steps ahead, status OK. Each doStep must be 100 steps, as from t = 0."""
    for start in (0.0, 1.7e9):
        fmu, refs = _started(damped_oscillator_fmu, start)
        before = np.array([1.0, 0.0])
        for i in range(6):
            fmu.doStep(start + i * 1e-4, 1e-4)
            after = np.array(fmu.getReal([refs["x"], refs["x_d"]]))
            assert _steps_between(before, after) == 100, (start, i)
            before = after
        fmu.terminate()
        fmu.freeInstance()


def test_a_time_too_coarse_for_the_step_is_refused(damped_oscillator_fmu):
    """Near t = 1e10 doubles are 1.9e-6 apart, more than step_size/4: steps of 1e-6 cannot be told
    apart in time, so the doStep is refused with the reason, not taken on a wrong grid."""
    logged = []
    fmu, _ = _started(damped_oscillator_fmu, 1e10, logger=lambda *args: logged.append(args[-1]))
    with pytest.raises(FMICallException):
        fmu.doStep(1e10, 1e-4)
    assert any(b"spacing of doubles" in message for message in logged)
    fmu.freeInstance()


def test_fmi2_instantiates_without_the_memory_functions_it_declares_it_does_not_use(tmp_path):
    """modelDescription.xml says canNotUseMemoryManagementFunctions="true" ("the callback functions
    allocateMemory and freeMemory given in fmi2Instantiate are ignored", FMI 2.0); was: NULL for an
    importer that passed none, with no log line."""
    fmu = export_fmu(double_pendulum(), tmp_path / "dp.fmu", x0={"q1": 1.0})
    zipfile.ZipFile(fmu).extractall(tmp_path / "x")
    root = ET.parse(tmp_path / "x" / "modelDescription.xml").getroot()
    assert root.find("CoSimulation").get("canNotUseMemoryManagementFunctions") == "true"
    lib = ctypes.CDLL(str(next((tmp_path / "x" / "binaries").rglob("*.so"))))
    logger_type = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                                   ctypes.c_char_p)

    class Callbacks(ctypes.Structure):
        _fields_ = [("logger", logger_type), ("allocateMemory", ctypes.c_void_p), ("freeMemory", ctypes.c_void_p),
                    ("stepFinished", ctypes.c_void_p), ("componentEnvironment", ctypes.c_void_p)]

    logger = logger_type(lambda *args: None)
    callbacks = Callbacks(logger, None, None, None, None)
    lib.fmi2Instantiate.restype = ctypes.c_void_p
    lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                                    ctypes.POINTER(Callbacks), ctypes.c_int, ctypes.c_int]
    lib.fmi2FreeInstance.argtypes = [ctypes.c_void_p]
    instance = lib.fmi2Instantiate(b"dp", 1, root.get("guid").encode(), b"", ctypes.byref(callbacks), 0, 0)
    assert instance
    lib.fmi2FreeInstance(instance)


@pytest.mark.parametrize("where", ["model name", "coordinate"])
def test_a_control_character_in_a_name_is_refused_by_name(tmp_path, where):
    """Was: an FMU whose modelDescription.xml no importer could parse ("invalid character in attribute
    value, line 21"); XML 1.0 has no U+0001."""
    t = me.dynamicsymbols._t
    x = sp.Function("x\x01" if where == "coordinate" else "x")(t)
    m, k = sp.symbols("m k", positive=True)
    model = Model("osc\x01" if where == "model name" else "osc", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=k * x ** 2 / 2, parameter_values={m: 1.0, k: 1.0})
    with pytest.raises(FmuError, match=r"U\+0001"):
        export_fmu(model, tmp_path / "osc.fmu", binary=False)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_setters_refuse_the_modes_the_standard_forbids(tmp_path, version):
    """FMI 2.0 and 3.0: after Terminate only getters, reset and free; in Model Exchange's
    Continuous-Time Mode no tunable parameter (only in Event Mode), and doStep is Co-Simulation's.
    Was: each accepted, the parameter taking effect (der(q1_d) jumped without an event)."""
    path = str(export_fmu(double_pendulum(), tmp_path / f"dp{version[0]}.fmu", x0={"q1": 1.0}, fmi_version=version))
    description = read_model_description(path)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    logged = []
    cs = instantiate_fmu(extract(path), description, fmi_type="CoSimulation",
                         logger=lambda *args: logged.append(args[-1]))
    if version == "2.0":
        cs.setupExperiment(startTime=0.0)
        cs.enterInitializationMode()
    else:
        cs.enterInitializationMode(startTime=0.0)
    cs.exitInitializationMode()
    cs.doStep(0.0, 0.01)
    cs.terminate()
    setter, getter = (cs.setReal, cs.getReal) if version == "2.0" else (cs.setFloat64, cs.getFloat64)
    m1 = getter([refs["m1"]])[0]
    with pytest.raises(FMICallException):
        setter([refs["m1"]], [5.0])
    assert getter([refs["m1"]])[0] == m1 and any(b"after Terminate" in message for message in logged)
    cs.freeInstance()
    me_fmu = instantiate_fmu(extract(path), description, fmi_type="ModelExchange")
    if version == "2.0":
        me_fmu.setupExperiment(startTime=0.0)
        me_fmu.enterInitializationMode()
        me_fmu.exitInitializationMode()
        me_fmu.newDiscreteStates()
        setter, getter = me_fmu.setReal, me_fmu.getReal
    else:
        me_fmu.enterInitializationMode(startTime=0.0)
        me_fmu.exitInitializationMode()
        me_fmu.updateDiscreteStates()
        setter, getter = me_fmu.setFloat64, me_fmu.getFloat64
    setter([refs["g"]], [9.0])  # Event Mode: allowed
    me_fmu.enterContinuousTimeMode()
    rate = getter([refs["der(q1_d)"]])[0]
    with pytest.raises(FMICallException):
        setter([refs["g"]], [1.0])
    assert getter([refs["der(q1_d)"]])[0] == rate
    me_fmu.freeInstance()
    if version == "2.0":
        me_fmu = instantiate_fmu(extract(path), description, fmi_type="ModelExchange")
        me_fmu.setupExperiment(startTime=0.0)
        me_fmu.enterInitializationMode()
        me_fmu.exitInitializationMode()
        me_fmu.dll.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        assert me_fmu.dll.fmi2DoStep(me_fmu.component, 0.0, 0.5, 1) == 3  # fmi2Error
        assert me_fmu.getReal([refs["q1"]])[0] == 1.0
        me_fmu.freeInstance()
