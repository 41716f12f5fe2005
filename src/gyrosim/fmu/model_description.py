"""modelDescription.xml for the gyrosim FMUs (FMI 2.0 and 3.0 co-simulation), written from ``Model.variables``.

One writer for both versions: every variable of the model (only the scene's), with its causality,
variability, unit, description and start value. Outputs have ``initial="exact"`` with the start value the
model computes from its initial state, so there are no InitialUnknowns (FMPy's validate_fmu checks them,
pythonfmu #131).
"""

from __future__ import annotations

import datetime
import math
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

from ..model import Model
from .slave import LOG_CATEGORIES, fmu_variables

__all__ = ["model_description", "UNITS"]

#: SI base-unit exponents of the units the model uses (FMI unit names, "." for products).
UNITS = {
    "1": {},
    "s": {"s": 1},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg.m2": {"kg": 1, "m": 2},
    "kg.m2/s": {"kg": 1, "m": 2, "s": -1},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "N.m.s": {"kg": 1, "m": 2, "s": -1},
    "J": {"kg": 1, "m": 2, "s": -2},
}


def _real(x) -> str:
    return repr(float(x))


def _units(units) -> Element:
    ud = Element("UnitDefinitions")
    for u in sorted(units):
        e = SubElement(ud, "Unit", name=u)
        SubElement(e, "BaseUnit", {k: str(v) for k, v in UNITS.get(u, {}).items()})
    return ud


def model_description(model: Model, model_identifier: str, fmi_version: int, token: str,
                      generation_tool: str) -> bytes:
    """The modelDescription.xml (UTF-8 bytes) of the FMU of ``model``.

    Parameters
    ----------
    model : Model
        A fresh model of the scene (its start values are written).
    model_identifier : str
    fmi_version : {2, 3}
    token : str
        GUID (FMI 2.0) / instantiationToken (FMI 3.0).
    generation_tool : str
    """
    scene = model.scene
    outputs = model.outputs(0)
    now = datetime.datetime.now(datetime.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    desc = scene.description or f"gyrosim rigid-body model, scene {scene.name}"
    attrib = {"fmiVersion": "2.0" if fmi_version == 2 else "3.0", "modelName": model_identifier,
              "description": desc, "generationTool": generation_tool, "generationDateAndTime": now,
              "variableNamingConvention": "structured"}
    if fmi_version == 2:
        attrib["guid"] = token
        attrib["numberOfEventIndicators"] = "0"
    else:
        attrib["instantiationToken"] = token
    root = Element("fmiModelDescription", attrib)
    variables = fmu_variables(model)
    units = {v.unit for _, v in variables if v.unit} | ({"s"} if fmi_version == 3 else set())
    if fmi_version == 2:
        SubElement(root, "CoSimulation", {
            "modelIdentifier": model_identifier, "needsExecutionTool": "true",
            "canHandleVariableCommunicationStepSize": "true", "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0", "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "true",
            "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true",
            "providesDirectionalDerivative": "false"})
        root.append(_units(units))
    else:
        SubElement(root, "CoSimulation", {
            "modelIdentifier": model_identifier, "needsExecutionTool": "true",
            "canBeInstantiatedOnlyOncePerProcess": "false", "canGetAndSetFMUState": "true",
            "canSerializeFMUState": "true", "providesDirectionalDerivatives": "false",
            "providesAdjointDerivatives": "false", "providesPerElementDependencies": "false",
            "canHandleVariableCommunicationStepSize": "true", "providesIntermediateUpdate": "false",
            "canReturnEarlyAfterIntermediateUpdate": "false", "hasEventMode": "false",
            "providesEvaluateDiscreteStates": "false"})
        root.append(_units(units))
    cats = SubElement(root, "LogCategories")
    for name, text in LOG_CATEGORIES.items():
        SubElement(cats, "Category", name=name, description=text)
    SubElement(root, "DefaultExperiment", startTime="0.0", stopTime=_real(scene.stop_time),
               tolerance=_real(model.tolerance), stepSize=_real(scene.output_interval))
    mv = SubElement(root, "ModelVariables")
    if fmi_version == 3:
        SubElement(mv, "Float64", name="time", valueReference="0", causality="independent",
                   variability="continuous", description="simulation time", unit="s")
    out_refs = []
    for vr, v in variables:
        start = outputs[v.name] if v.causality == "output" else v.start
        a = {"name": v.name, "valueReference": str(vr), "description": v.description, "causality": v.causality,
             "variability": v.variability}
        if v.causality == "output":
            a["initial"] = "exact"
            out_refs.append(vr)
        elif v.causality == "parameter":
            a["initial"] = "exact"
        if fmi_version == 2:
            sv = SubElement(mv, "ScalarVariable", a)
            if v.type == "String":
                SubElement(sv, "String", start=str(start))
            else:
                ta = {"start": _real(start)}
                if v.unit:
                    ta["unit"] = v.unit
                SubElement(sv, "Real", ta)
        else:
            if v.type == "String":
                e = SubElement(mv, "String", a)
                SubElement(e, "Start", value=str(start))
            else:
                if v.unit:
                    a["unit"] = v.unit
                a["start"] = _real(start)
                SubElement(mv, "Float64", a)
        if v.type == "Real" and not math.isfinite(float(start)):
            raise ValueError(f"start value of {v.name} is not finite: {start!r}")
    ms = SubElement(root, "ModelStructure")
    if fmi_version == 2:
        if out_refs:
            o = SubElement(ms, "Outputs")
            index = {vr: i + 1 for i, (vr, _) in enumerate(variables)}
            for vr in out_refs:
                SubElement(o, "Unknown", index=str(index[vr]))
    else:
        for vr in out_refs:
            SubElement(ms, "Output", valueReference=str(vr))
    return parseString(tostring(root, "UTF-8")).toprettyxml(indent="  ", encoding="UTF-8")
