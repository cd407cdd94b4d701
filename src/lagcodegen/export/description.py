"""Helper of the FMU export: ``modelDescription.xml`` (FMI 2.0 and 3.0) from the variable table.

One description holds both interfaces, Model Exchange and Co-Simulation, with the same model
identifier and sources. Element order and attribute names follow the standards' schemas
(fmi2ModelDescription.xsd, fmi3ModelDescription.xsd); FMPy validates them against those.
Deterministic: no date, no host.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

from .variables import VariableTable


def model_description(table: VariableTable, *, model_name: str, identifier: str, guid: str,
                      description: str, tool: str, sources: tuple, step: float, constrained: bool = False) -> str:
    """The XML text. ``sources``: the C files of ``sources/`` that the FMU builds from; ``constrained``:
    Model Exchange asks for fmi2CompletedIntegratorStep, where the drift from the constraints is checked
    (found by review: CVode carried a four-bar 0.28 m off its loop with OK and nothing logged)."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": model_name, "guid": guid, "description": description,
        "generationTool": tool, "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    me = ET.SubElement(root, "ModelExchange", {
        "modelIdentifier": identifier, "canNotUseMemoryManagementFunctions": "true",
        "completedIntegratorStepNotNeeded": "false" if constrained else "true"})
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "canHandleVariableCommunicationStepSize": "true",
        "canNotUseMemoryManagementFunctions": "true"})
    for interface in (me, cs):
        files = ET.SubElement(interface, "SourceFiles")
        for name in sources:
            ET.SubElement(files, "File", {"name": name})
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError", "description": "errors: what failed and why"})
    ET.SubElement(categories, "Category", {"name": "logStatusWarning",
                                           "description": "warnings: a state off the model's constraints"})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stepSize": repr(float(step))})
    variables = ET.SubElement(root, "ModelVariables")
    for v in table.variables:
        attributes = {"name": v.name, "valueReference": str(v.value_reference), "description": v.description,
                      "causality": v.causality, "variability": v.variability}
        if v.initial is not None:
            attributes["initial"] = v.initial
        scalar = ET.SubElement(variables, "ScalarVariable", attributes)
        real = {} if v.start is None else {"start": repr(float(v.start))}
        if v.derivative_of is not None:
            real["derivative"] = str(v.derivative_of)
        ET.SubElement(scalar, "Real", real)
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in table.variables if v.causality == "output"]
    derivatives = table.of_kind("derivative")
    initial = [v for v in table.variables if v.initial == "calculated"]  # outputs and derivatives computed at init
    for tag, rows in (("Outputs", outputs), ("Derivatives", derivatives), ("InitialUnknowns", initial)):
        if rows:
            element = ET.SubElement(structure, tag)
            for v in sorted(rows, key=lambda v: v.index):
                ET.SubElement(element, "Unknown", {"index": str(v.index)})
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def model_description_fmi3(table: VariableTable, *, model_name: str, identifier: str, token: str,
                           description: str, tool: str, step: float, constrained: bool = False) -> str:
    """The FMI 3.0 XML text (fmi3ModelDescription.xsd): Float64 variables, ``time`` independent,
    ModelStructure by value reference; the sources are listed in `build_description`."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": model_name, "instantiationToken": token, "description": description,
        "generationTool": tool, "variableNamingConvention": "flat"})
    ET.SubElement(root, "ModelExchange", {"modelIdentifier": identifier,
                                          "needsCompletedIntegratorStep": "true" if constrained else "false"})
    ET.SubElement(root, "CoSimulation", {"modelIdentifier": identifier, "hasEventMode": "false",
                                         "canHandleVariableCommunicationStepSize": "true"})
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError", "description": "errors: what failed and why"})
    ET.SubElement(categories, "Category", {"name": "logStatusWarning",
                                           "description": "warnings: a state off the model's constraints"})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stepSize": repr(float(step))})
    variables = ET.SubElement(root, "ModelVariables")
    by_vr = {v.index: v.value_reference for v in table.variables}
    for v in table.of_kind("time") + tuple(v for v in table.variables if v.kind != "time"):
        attributes = {"name": v.name, "valueReference": str(v.value_reference), "description": v.description,
                      "causality": v.causality, "variability": v.variability}
        if v.initial is not None:
            attributes["initial"] = v.initial
        if v.start is not None:
            attributes["start"] = repr(float(v.start))
        if v.derivative_of is not None:
            attributes["derivative"] = str(by_vr[v.derivative_of])
        ET.SubElement(variables, "Float64", attributes)
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in table.variables if v.causality == "output"]
    initial = [v for v in table.variables if v.initial == "calculated"]
    for tag, rows in (("Output", outputs), ("ContinuousStateDerivative", table.of_kind("derivative")),
                      ("InitialUnknown", initial)):
        for v in sorted(rows, key=lambda v: v.value_reference):
            ET.SubElement(structure, tag, {"valueReference": str(v.value_reference)})
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def build_description(identifier: str, sources: tuple) -> str:
    """``sources/buildDescription.xml`` (FMI 3.0): the C99 files that build ``identifier``."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    configuration = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": identifier})
    files = ET.SubElement(configuration, "SourceFileSet", {"language": "C99"})
    for name in sources:
        ET.SubElement(files, "SourceFile", {"name": name})
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
