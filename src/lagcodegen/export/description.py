"""Helper of the FMU export: ``modelDescription.xml`` (FMI 2.0) from the variable table.

One description holds both interfaces, Model Exchange and Co-Simulation, with the same model
identifier and sources. Element order and attribute names follow the FMI 2.0 standard
(fmi2ModelDescription.xsd); FMPy's validation checks them. Deterministic: no date, no host.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

from .variables import VariableTable


def model_description(table: VariableTable, *, model_name: str, identifier: str, guid: str,
                      description: str, tool: str, sources: tuple, step: float) -> str:
    """The XML text. ``sources``: the C files of ``sources/`` that the FMU builds from."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": model_name, "guid": guid, "description": description,
        "generationTool": tool, "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    me = ET.SubElement(root, "ModelExchange", {
        "modelIdentifier": identifier, "canNotUseMemoryManagementFunctions": "true",
        "completedIntegratorStepNotNeeded": "true"})
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "canHandleVariableCommunicationStepSize": "true",
        "canNotUseMemoryManagementFunctions": "true"})
    for interface in (me, cs):
        files = ET.SubElement(interface, "SourceFiles")
        for name in sources:
            ET.SubElement(files, "File", {"name": name})
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError", "description": "errors: what failed and why"})
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
