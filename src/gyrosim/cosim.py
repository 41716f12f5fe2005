"""A real co-simulation: the gyrosim body FMU and an attitude-controller FMU coupled by an SSP system structure.

``build_system`` writes ``<out>/attitude_control.ssp``: a zip holding ``SystemStructure.ssd`` (SSP 1.0) and, under
``resources/``, two FMI 2.0 co-simulation FMUs built from C:

* ``body`` - the gyrosim engine (:func:`gyrosim.fmu.build.build_fmu`) of a free body with torque inputs and no
  gravity (:func:`control_scene`), starting at rest at ``q0``;
* ``controller`` - :mod:`gyrosim.fmu.controller`, a PD law on the quaternion error, its gains (``Kp_*``, ``Kd_*``,
  from ``zeta`` and ``wn`` by :func:`~gyrosim.fmu.controller.pd_gains`) and target (``qt_*``) bound by the SSD's
  inline parameter set.

Connections: ``controller.tau_{x,y,z} -> body.tau_{x,y,z}``; ``body.q_{w,x,y,z}`` and ``body.omega_{x,y,z}`` ->
the controller's inputs of the same names. The SSD's ``DefaultExperiment`` carries the stop time and, as an OSP
annotation (``osp:FixedStepAlgorithm baseStepSize``), the communication step.

Two masters run it, both the same fixed-step Jacobi scheme (every FMU steps from the values of the previous
communication point, then the outputs go to the inputs):

* :func:`run_libcosim` - libcosim's own SSP loader (``libcosimpy``; ``CosimExecution.from_ssp_file``);
* :func:`run_fmpy` - a small master of ours over FMPy's ``FMU2Slave``, reading the structure with FMPy's SSP reader
  (``fmpy.ssp.ssd.read_ssd``, which validates the SSD against the SSP 1.0 schema) and initialising as libcosim does
  (inputs exchanged in initialisation mode, so the first step already sees the body's attitude).

FMPy's own master, ``fmpy.ssp.simulation.simulate_ssp``, also runs the file (:func:`run_fmpy_ssp`), but it starts
every connection at 0 (no exchange before the first step: the controller's first input is the quaternion 0 and the
body's first torque 0) and applies component parameter bindings only through its ``parameter_set`` argument (we pass
the SSD's); so it settles the same way but differs from the two above over the first steps.

With the Jacobi exchange the torque over ``[t_k, t_k+1]`` is the law at the state of ``t_k-1`` (at ``t_0`` for the
first two steps): :func:`linear_prediction` gives the linearised closed loop both as the continuous
``I theta'' + Kd theta' + Kp theta = 0`` and with that exact sampled-data delay.
"""

from __future__ import annotations

import math
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._atomic import atomic_path, check_writable
from .errors import ConfigError, GyrosimError

__all__ = ["control_scene", "build_system", "read_experiment", "with_parameters", "axis_angle", "run_libcosim",
           "run_fmpy", "run_fmpy_ssp", "linear_prediction", "settling_time", "error_angles", "plot_results",
           "register", "CosimResult", "DEFAULTS"]

NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
      "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}
BODY_OUT = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z")
TORQUES = ("tau_x", "tau_y", "tau_z")

#: The demo system: a body of principal moments (1, 2, 3) kg m^2 at rest at the identity, to be turned by 0.25 rad
#: about (1, 2, 2)/3 with zeta = 0.7, wn = 2 rad/s on every axis; communication step 0.01 s, 8 s.
DEFAULTS = {"moments": (1.0, 2.0, 3.0), "q0": (1.0, 0.0, 0.0, 0.0), "omega0": (0.0, 0.0, 0.0),
            "target_axis": (1.0, 2.0, 2.0), "target_angle": 0.25, "zeta": 0.7, "wn": 2.0, "step": 0.01,
            "stop_time": 8.0}


def axis_angle(axis, angle) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a turn by ``angle`` (rad) about ``axis``."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    return np.array([math.cos(angle / 2), *(math.sin(angle / 2) * a)])


def control_scene(moments=DEFAULTS["moments"], q0=DEFAULTS["q0"], omega0=DEFAULTS["omega0"]):
    """The controlled body: a free body (no pivot, so no gravity) with ``torque_input = true``, integrated by rk4
    at 1 ms, with the health monitor on (its work-energy balance integrates the controller's torque)."""
    from .scene import scene_from_dict

    return scene_from_dict({
        "scene": {"name": "controlled_body", "description": "free body with torque inputs (attitude control)",
                  "integrator": "rk4", "max_step": 1e-3, "output_interval": DEFAULTS["step"],
                  "stop_time": DEFAULTS["stop_time"]},
        "body": [{"name": "body", "inertia": {"principal": [float(m) for m in moments]}, "torque_input": True,
                  "attitude": {"q": [float(x) for x in q0]}, "rates": {"omega": [float(w) for w in omega0]}}]},
        source="<gyrosim.cosim>")


def _ssd(body_fmu: str, ctrl_fmu: str, params: dict[str, float], step: float, stop_time: float) -> str:
    ssd, ssc, ssv, osp = (f"{{{NS[k]}}}" for k in ("ssd", "ssc", "ssv", "osp"))
    for k, v in NS.items():
        ET.register_namespace(k, v)
    root = ET.Element(ssd + "SystemStructureDescription", name="attitude_control", version="1.0")
    system = ET.SubElement(root, ssd + "System", name="attitude_control",
                           description="gyrosim body under a PD attitude controller")
    elements = ET.SubElement(system, ssd + "Elements")

    def component(name, source, connectors):
        c = ET.SubElement(elements, ssd + "Component", name=name, source=source,
                          type="application/x-fmu-sharedlibrary", implementation="CoSimulation")
        cs = ET.SubElement(c, ssd + "Connectors")
        for n, kind in connectors:
            ET.SubElement(ET.SubElement(cs, ssd + "Connector", name=n, kind=kind), ssc + "Real")
        return c

    component("body", body_fmu, [*((n, "output") for n in BODY_OUT), *((n, "input") for n in TORQUES)])
    ctrl = component("controller", ctrl_fmu,
                     [*((n, "input") for n in BODY_OUT), *((n, "output") for n in (*TORQUES, "error_angle"))])
    pv = ET.SubElement(ET.SubElement(ET.SubElement(ctrl, ssd + "ParameterBindings"), ssd + "ParameterBinding"),
                       ssd + "ParameterValues")
    ps = ET.SubElement(pv, ssv + "ParameterSet", version="1.0", name="pd")
    pars = ET.SubElement(ps, ssv + "Parameters")
    for n, v in params.items():
        ET.SubElement(ET.SubElement(pars, ssv + "Parameter", name=n), ssv + "Real", value=repr(float(v)))
    conns = ET.SubElement(system, ssd + "Connections")
    for n in TORQUES:
        ET.SubElement(conns, ssd + "Connection", startElement="controller", startConnector=n, endElement="body",
                      endConnector=n)
    for n in BODY_OUT:
        ET.SubElement(conns, ssd + "Connection", startElement="body", startConnector=n, endElement="controller",
                      endConnector=n)
    de = ET.SubElement(root, ssd + "DefaultExperiment", startTime="0", stopTime=repr(float(stop_time)))
    ann = ET.SubElement(ET.SubElement(de, ssd + "Annotations"), ssc + "Annotation", type="com.opensimulationplatform")
    ET.SubElement(ET.SubElement(ann, osp + "Algorithm"), osp + "FixedStepAlgorithm", baseStepSize=repr(float(step)))
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def build_system(out_dir, *, moments=DEFAULTS["moments"], q0=DEFAULTS["q0"], omega0=DEFAULTS["omega0"],
                 q_target=None, zeta=DEFAULTS["zeta"], wn=DEFAULTS["wn"], step=DEFAULTS["step"],
                 stop_time=DEFAULTS["stop_time"], name="attitude_control") -> Path:
    """Build both FMUs and write ``<out_dir>/<name>.ssp`` (see the module docstring); returns its path.

    ``q_target`` defaults to a turn of ``DEFAULTS["target_angle"]`` about ``DEFAULTS["target_axis"]``."""
    from .fmu.build import build_fmu
    from .fmu.controller import build_controller, pd_gains

    if q_target is None:
        q_target = axis_angle(DEFAULTS["target_axis"], DEFAULTS["target_angle"])
    params = pd_gains(moments, zeta, wn)
    params.update(zip(("qt_w", "qt_x", "qt_y", "qt_z"), (float(x) for x in q_target)))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ssp = out_dir / f"{name}.ssp"
    with tempfile.TemporaryDirectory(prefix="gyrosim_ssp_") as tmp:
        res = Path(tmp) / "resources"
        body = build_fmu(control_scene(moments, q0, omega0), 2, res)
        ctrl = build_controller(res)
        text = _ssd(f"resources/{body.name}", f"resources/{ctrl.name}", params, step, stop_time)
        with atomic_path(ssp) as tmp_ssp, zipfile.ZipFile(tmp_ssp, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("SystemStructure.ssd", text)
            zf.write(body, f"resources/{body.name}")
            zf.write(ctrl, f"resources/{ctrl.name}")
    return ssp


def with_parameters(ssp, out, **params) -> Path:
    """Copy ``ssp`` to ``out`` with the controller's bound parameters changed (``qt_w=...``, ``Kp_x=...``): the
    same FMUs, a new parameter set in the SSD. Raises KeyError for a name the SSD does not bind."""
    with zipfile.ZipFile(ssp) as zf:
        items = {n: zf.read(n) for n in zf.namelist()}
    for k, v in NS.items():
        ET.register_namespace(k, v)
    root = ET.fromstring(items["SystemStructure.ssd"])
    bound = {p.get("name"): p for p in root.iterfind(".//ssd:Component[@name='controller']//ssv:Parameter", NS)}
    for name, value in params.items():
        bound[name].find("ssv:Real", NS).set("value", repr(float(value)))
    items["SystemStructure.ssd"] = ('<?xml version="1.0" encoding="UTF-8"?>\n'
                                    + ET.tostring(root, encoding="unicode") + "\n").encode()
    out = Path(out)
    with atomic_path(out) as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for n, data in items.items():
            zf.writestr(n, data)
    return out


@dataclass
class Experiment:
    """What the SSD says about the run: the stop time, the communication step, the controller's parameters."""

    stop_time: float
    step: float
    params: dict[str, float]


def read_experiment(ssp) -> Experiment:
    """The DefaultExperiment (stop time, OSP base step) and the controller's bound parameters of an ``.ssp``.

    Raises
    ------
    ConfigError
        The file is not an SSP (a zip holding ``SystemStructure.ssd``: an MCAP recording, a CSV, ...), or its SSD
        does not read (the message names the file and what is wrong).
    """
    what = "an SSP file: a zip holding SystemStructure.ssd (gyrosim cosim SYSTEM.ssp --build writes one)"
    try:
        with zipfile.ZipFile(ssp) as zf:
            root = ET.fromstring(zf.read("SystemStructure.ssd"))
        de = root.find("ssd:DefaultExperiment", NS)
        stop = float(de.get("stopTime", DEFAULTS["stop_time"])) if de is not None else DEFAULTS["stop_time"]
        fs = root.find(".//osp:FixedStepAlgorithm", NS)
        step = float(fs.get("baseStepSize")) if fs is not None else DEFAULTS["step"]
        params = {}
        for c in root.findall("ssd:System/ssd:Elements/ssd:Component", NS):
            if c.get("name") == "controller":
                for p in c.findall(".//ssv:Parameter", NS):
                    params[p.get("name")] = float(p.find("ssv:Real", NS).get("value"))
    except zipfile.BadZipFile as e:
        raise ConfigError("SYSTEM", str(ssp), f"{what}; this is not a zip ({e})") from None
    except KeyError:
        raise ConfigError("SYSTEM", str(ssp), f"{what}; this zip has no SystemStructure.ssd") from None
    except (ET.ParseError, ValueError, TypeError, AttributeError) as e:
        raise ConfigError("SYSTEM", str(ssp), f"{what}; its SystemStructure.ssd does not read ({e})") from None
    return Experiment(stop, step, params)


@dataclass
class CosimResult:
    """One run, sampled at the communication points ``t`` (n + 1 rows from t = 0): the body's attitude ``q``
    (n+1, 4) and rates ``omega`` (n+1, 3), and the torque ``tau`` (n+1, 3) the body held over the step that
    starts at each point (the last row: the torque at the end). ``master`` names who ran it."""

    master: str
    t: np.ndarray
    q: np.ndarray
    omega: np.ndarray
    tau: np.ndarray

    def error_angle(self, q_target) -> np.ndarray:
        return error_angles(self.q, q_target)


def error_angles(q, q_target) -> np.ndarray:
    """Angle (rad) of the rotation from ``q_target`` to each attitude row of ``q``: ``2 atan2(|v|, |w|)`` of
    ``conj(q_target) * q``."""
    q = np.asarray(q, float)
    t = np.asarray(q_target, float) / np.linalg.norm(q_target)
    w = q @ t
    v = t[0] * q[:, 1:] - q[:, :1] * t[1:] - np.cross(t[1:], q[:, 1:])
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w))


def _steps(stop_time: float, step: float) -> int:
    """The number of communication steps of ``step`` s in ``stop_time`` s; ConfigError unless both are finite and
    > 0 and the stop time is a whole number of steps."""
    for name, value in (("stop_time", stop_time), ("step", step)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ConfigError(name, value, "a finite number > 0 in s")
    n = round(stop_time / step)
    if n < 1 or abs(n * step - stop_time) > 1e-9 * max(1.0, stop_time):
        raise ConfigError("stop_time", stop_time, f"a whole number of communication steps of {step!r} s")
    return n


def run_libcosim(ssp, *, step: float | None = None, stop_time: float | None = None) -> CosimResult:
    """Run the system with libcosim's SSP loader (libcosimpy): fixed-step Jacobi at ``step`` (default the SSD's),
    times in integer nanoseconds. Raises RuntimeError if libcosim cannot load or step it."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)   # its default is a trace of every FMI call

    exp = read_experiment(ssp)
    step = exp.step if step is None else step
    stop_time = exp.stop_time if stop_time is None else stop_time
    n = _steps(stop_time, step)
    h_ns = round(step * 1e9)
    ex = CosimExecution.from_ssp_file(str(Path(ssp).resolve()), step_size=h_ns)
    if ex is None or ex.num_slaves() != 2:
        raise RuntimeError(f"libcosim could not load {ssp}")
    body = ex.slave_index_from_instance_name("body")
    ctrl = ex.slave_index_from_instance_name("controller")
    vr_body = {v.name.decode(): v.reference for v in ex.slave_variables(body)}
    vr_ctrl = {v.name.decode(): v.reference for v in ex.slave_variables(ctrl)}
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    refs_b = [vr_body[n] for n in (*BODY_OUT, *TORQUES)]
    refs_c = [vr_ctrl[n] for n in TORQUES]
    rows, ctrl_rows = [], []
    for k in range(n):
        if not ex.step(1):
            raise RuntimeError(f"libcosim failed at step {k} of {ssp}")
        rows.append(obs.last_real_values(body, refs_b))
        ctrl_rows.append(obs.last_real_values(ctrl, refs_c))
    del ex, obs
    rows, ctrl_rows = np.array(rows, float), np.array(ctrl_rows, float)
    # after step k+1 the observer shows the body's state at t_k+1 and the torque it held over [t_k, t_k+1], and the
    # controller's output, which the body holds over the next step
    q0, om0 = _start_state(ssp)
    y = np.vstack([[*q0, *om0], rows[:, :7]])
    tau = np.vstack([rows[:1, 7:], ctrl_rows])
    t = np.arange(n + 1) * step
    return CosimResult("libcosim", t, y[:, :4], y[:, 4:7], tau)


def _start_state(ssp):
    """The body FMU's start values of q and omega (its model description)."""
    from fmpy import read_model_description

    with tempfile.TemporaryDirectory() as tmp, zipfile.ZipFile(ssp) as zf:
        name = next(n for n in zf.namelist() if n.startswith("resources/") and "Controller" not in n)
        path = zf.extract(name, tmp)
        md = read_model_description(path)
    start = {v.name: float(v.start) for v in md.modelVariables if v.name in BODY_OUT}
    return [start[n] for n in BODY_OUT[:4]], [start[n] for n in BODY_OUT[4:]]


def run_fmpy(ssp, *, step: float | None = None, stop_time: float | None = None) -> CosimResult:
    """Run the system with our master over FMPy's ``FMU2Slave``: the structure from FMPy's SSP reader, the
    parameters from the SSD's binding, initial values exchanged in initialisation mode, then fixed-step Jacobi
    (both FMUs step, then every connection is transferred) - libcosim's scheme."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.ssp.ssd import read_ssd

    exp = read_experiment(ssp)
    step = exp.step if step is None else step
    stop_time = exp.stop_time if stop_time is None else stop_time
    n = _steps(stop_time, step)
    ssd = read_ssd(str(ssp))
    comps = {c.name: c for c in ssd.system.elements}
    conns = [(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections]
    slaves, vrs, dirs = {}, {}, []
    with tempfile.TemporaryDirectory(prefix="gyrosim_cosim_") as tmp:
        try:
            for name, comp in comps.items():
                fmu = zipfile.ZipFile(ssp).extract(comp.source, tmp)
                md = read_model_description(fmu)
                d = extract(fmu, str(Path(tmp) / name))
                dirs.append(d)
                vrs[name] = {v.name: v.valueReference for v in md.modelVariables}
                s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                              instanceName=name)
                s.instantiate()
                s.setupExperiment(startTime=0.0, stopTime=stop_time)
                for b in comp.parameterBindings:
                    for pset in b.parameterValues:
                        for p in pset.parameters:
                            s.setReal([vrs[name][p.name]], [float(p.value)])
                s.enterInitializationMode()
                slaves[name] = s

            def transfer():
                vals = [slaves[a].getReal([vrs[a][ac]])[0] for a, ac, _, _ in conns]
                for (_, _, b, bc), v in zip(conns, vals):
                    slaves[b].setReal([vrs[b][bc]], [v])

            for _ in range(len(slaves)):   # libcosim: as many exchange rounds as simulators
                transfer()
            for s in slaves.values():
                s.exitInitializationMode()
            body = slaves["body"]
            refs = [vrs["body"][n] for n in (*BODY_OUT, *TORQUES)]
            rows = [body.getReal(refs)]
            t = 0.0
            for k in range(n):
                for s in slaves.values():
                    s.doStep(currentCommunicationPoint=t, communicationStepSize=step)
                t = (k + 1) * step
                out = body.getReal(refs[:7])
                transfer()
                rows.append(list(out) + list(body.getReal(refs[7:])))
        finally:
            for s in slaves.values():
                s.terminate()
                s.freeInstance()
    y = np.array(rows, float)
    return CosimResult("fmpy", np.arange(n + 1) * step, y[:, :4], y[:, 4:7], y[:, 7:])


def run_fmpy_ssp(ssp, *, step: float | None = None, stop_time: float | None = None) -> CosimResult:
    """Run the system with FMPy's own SSP master (``fmpy.ssp.simulation.simulate_ssp``), the SSD's controller
    parameters passed as its ``parameter_set`` (it does not apply component bindings itself). It starts every
    connection at 0 (see the module docstring). Its rows are labelled with the start of each step but hold the values
    at its end: here they are relabelled to the end, and the start row is the body's start."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    exp = read_experiment(ssp)
    step = exp.step if step is None else step
    stop_time = exp.stop_time if stop_time is None else stop_time
    n = _steps(stop_time, step)
    ssd = read_ssd(str(ssp))
    pset = ParameterSet(name="pd")
    for c in ssd.system.elements:
        for b in c.parameterBindings:
            for ps in b.parameterValues:
                for p in ps.parameters:
                    pset.parameters.append(Parameter(name=f"{c.name}.{p.name}", type=p.type, value=p.value))
    # its loop runs while time < stop_time with time += step: stop half a step early to get exactly n steps
    r = simulate_ssp(str(ssp), stop_time=(n - 0.5) * step, step_size=step, parameter_set=pset)
    if len(r) != n:
        raise RuntimeError(f"fmpy simulate_ssp made {len(r)} steps, expected {n}")
    y = np.column_stack([r[f"body.{c}"] for c in (*BODY_OUT, *TORQUES)])
    q0, om0 = _start_state(ssp)
    y = np.vstack([[*q0, *om0, 0.0, 0.0, 0.0], y])
    return CosimResult("fmpy.ssp", np.arange(n + 1) * step, y[:, :4], y[:, 4:7], y[:, 7:])


def linear_prediction(moments, params, q0, omega0, t, *, step: float | None = None) -> np.ndarray:
    """The linearised closed loop, per axis ``I_i theta'' + Kd_i theta' + Kp_i theta = 0`` with ``theta(0) =
    2 s vec(conj(q_target) q0)`` and ``theta'(0) = omega0``; returns theta (len(t), 3) at the times ``t``.

    ``step=None``: the continuous loop. ``step=h``: the sampled-data loop the Jacobi masters make (``t`` must then
    be the communication points ``k h``): the torque over ``[t_k, t_k+1]`` is the law at ``t_max(k-1, 0)``, held
    (zero-order hold), the body's motion between points exact."""
    from scipy.linalg import expm

    qt = np.array([params[f"qt_{c}"] for c in "wxyz"], float)
    qt /= np.linalg.norm(qt)
    q = np.asarray(q0, float) / np.linalg.norm(q0)
    ew = qt @ q
    ev = qt[0] * q[1:] - q[0] * qt[1:] - np.cross(qt[1:], q[1:])
    th0 = 2.0 * math.copysign(1.0, ew if ew != 0 else 1.0) * ev
    t = np.asarray(t, float)
    out = np.empty((len(t), 3))
    for i, ax in enumerate("xyz"):
        inertia, kp, kd = float(moments[i]), params[f"Kp_{ax}"], params[f"Kd_{ax}"]
        x0 = np.array([th0[i], float(omega0[i])])
        if step is None:
            a = np.array([[0.0, 1.0], [-kp / inertia, -kd / inertia]])
            dt = np.diff(t)
            if len(t) > 2 and np.allclose(dt, dt[0], rtol=1e-9, atol=0.0):   # a uniform grid: one exponential
                phi, x = expm(a * dt[0]), expm(a * t[0]) @ x0
                for k in range(len(t)):
                    out[k, i] = x[0]
                    x = phi @ x
            else:
                out[:, i] = [(expm(a * tk) @ x0)[0] for tk in t]
            continue
        phi = np.array([[1.0, step], [0.0, 1.0]])
        gam = np.array([step * step / 2, step]) / inertia
        gain = np.array([kp, kd])
        xs = [x0]
        for k in range(len(t) - 1):
            u = -gain @ xs[max(k - 1, 0)]
            xs.append(phi @ xs[-1] + gam * u)
        out[:, i] = np.array(xs)[:, 0]
    return out


def settling_time(t, angle, frac: float = 0.02) -> float:
    """The first time after which ``angle`` stays within ``frac`` of ``angle[0]`` (linear interpolation at the
    crossing); 0 if it never leaves, ``inf`` if it is outside at the end."""
    t, angle = np.asarray(t, float), np.abs(np.asarray(angle, float))
    band = frac * angle[0]
    out = np.nonzero(angle > band)[0]
    if len(out) == 0:
        return 0.0
    k = out[-1]
    if k == len(t) - 1:
        return math.inf
    a0, a1 = angle[k], angle[k + 1]
    return float(t[k] + (t[k + 1] - t[k]) * (a0 - band) / (a0 - a1))


def plot_results(results, path, q_target, prediction=None, title="attitude control co-simulation"):
    """A PNG: the error angle of each run (log scale) against the linearised prediction, with the 2 % band, and
    the torques of the first run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7), sharex=True, constrained_layout=True)
    styles = ["-", "--", ":"]
    first = results[0]
    th0 = first.error_angle(q_target)[0]
    if prediction is not None:
        tp, thp = prediction
        ax1.semilogy(tp, np.maximum(np.linalg.norm(thp, axis=1), 1e-12), color="0.6", lw=3,
                     label="linearised prediction (continuous)")
    for r, ls in zip(results, styles):
        ax1.semilogy(r.t, np.maximum(r.error_angle(q_target), 1e-12), ls, lw=1.2, label=r.master)
    ax1.axhline(0.02 * th0, color="k", lw=0.6, ls="-.")
    ax1.text(first.t[-1], 0.02 * th0, " 2 % band", va="bottom", ha="right", fontsize=8)
    ax1.set_ylabel("angle to the target (rad)")
    ax1.set_ylim(1e-7, 2 * th0)
    ax1.legend(loc="upper right", fontsize=8)
    ax1.set_title(title)
    for i, c in enumerate("xyz"):
        ax2.plot(first.t, first.tau[:, i], lw=1.2, label=f"tau_{c} ({first.master})")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("control torque (N m)")
    ax2.legend(loc="upper right", fontsize=8)
    path = Path(path)
    fmt = path.suffix[1:].lower()
    if fmt not in fig.canvas.get_supported_filetypes():
        fmt = "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=fmt)
    plt.close(fig)
    return path


# --- gyrosim cosim ---------------------------------------------------------------------------------------------

def register(subparsers) -> None:
    """Add ``cosim`` to the ``gyrosim`` parser: ``gyrosim cosim SYSTEM.ssp [--build] [--master ...] [--plot PNG]``."""
    from .cli import add_verbosity

    p = subparsers.add_parser(
        "cosim", help="run an SSP system (the body FMU under the attitude-controller FMU)",
        description="Run SYSTEM.ssp with libcosim and/or FMPy (docs/cosim.md). --build first writes the demo "
                    "system (the gyrosim body FMU and the PD attitude-controller FMU) to SYSTEM.ssp. Every "
                    "argument is checked before any work; files are replaced only when they are complete.")
    p.add_argument("ssp", type=Path, metavar="SYSTEM.ssp",
                   help="the .ssp file (SystemStructure.ssd and resources/*.fmu)")
    p.add_argument("--build", action="store_true", help="build the demo system into SYSTEM.ssp first")
    p.add_argument("--master", choices=("libcosim", "fmpy", "fmpy-ssp", "all"), default="all",
                   help="who runs it (default: all: libcosim, our FMPy master and FMPy's simulate_ssp)")
    p.add_argument("--stop-time", type=float, default=None, metavar="T",
                   help="simulated seconds (default: the SSD's)")
    p.add_argument("--step", type=float, default=None, metavar="H",
                   help="communication step in s (default: the SSD's)")
    p.add_argument("--plot", type=Path, default=None, metavar="FILE.png",
                   help="write a PNG of the error angle and torques")
    add_verbosity(p)
    p.set_defaults(func=cmd_cosim)


_MASTERS = {"libcosim": ("libcosimpy", "cosim"), "fmpy": ("fmpy", "fmu"), "fmpy-ssp": ("fmpy", "fmu")}


def check_cosim_args(args) -> tuple[list[str], Experiment]:
    """Every check of ``gyrosim cosim``'s arguments, before any work: the numbers, the masters' packages, the
    system file (or, with ``--build``, where it goes), the step against the stop time, the plot path. Returns the
    masters to run and the experiment (the SSD's, or the demo's with ``--build``, with the flags applied)."""
    import importlib.util

    for flag, value in (("--stop-time", args.stop_time), ("--step", args.step)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ConfigError(flag, value, "a finite number > 0 in s")
    names = list(_MASTERS) if args.master == "all" else [args.master]
    for m in names:
        module, extra = _MASTERS[m]
        if importlib.util.find_spec(module) is None:
            raise GyrosimError(f"--master {m} needs {module}, which is not installed: pip install 'gyrosim[{extra}]'"
                               + (" (or choose --master fmpy)" if m == "libcosim" else ""))
    if args.build:
        if args.ssp.suffix != ".ssp":
            raise ConfigError("SYSTEM.ssp", str(args.ssp), "a path ending in .ssp (--build writes the system there)")
        if args.ssp.is_dir():
            raise GyrosimError(f"SYSTEM.ssp {str(args.ssp)!r} cannot be written: it is a folder")
        check_writable(args.ssp, "SYSTEM.ssp")  # its folder must exist (docs/cli.md, "Output paths")
        exp = Experiment(DEFAULTS["stop_time"], DEFAULTS["step"], {})
    else:
        if not args.ssp.exists():
            raise GyrosimError(f"SYSTEM.ssp {str(args.ssp)!r} not found (add --build to write the demo system)")
        if args.ssp.is_dir():
            raise ConfigError("SYSTEM", str(args.ssp), "an SSP file (this is a folder)")
        exp = read_experiment(args.ssp)
    step = exp.step if args.step is None else args.step
    stop = exp.stop_time if args.stop_time is None else args.stop_time
    n = round(stop / step)
    if n < 1 or abs(n * step - stop) > 1e-9 * max(1.0, stop):
        raise ConfigError("--stop-time" if args.stop_time is not None else "--step",
                          args.stop_time if args.stop_time is not None else args.step,
                          f"a whole number of communication steps: stop time {stop!r} s, step {step!r} s")
    if args.plot is not None:
        check_writable(args.plot, "--plot")
    return names, Experiment(stop, step, exp.params)


def cmd_cosim(args) -> int:
    """Handler of ``gyrosim cosim``: every argument checked first (:func:`check_cosim_args`; exit code 2, one
    line), then the build, the runs and the plot. A master that fails is a run-time failure (exit code 1)."""
    from .cli import verbosity

    v = verbosity(args)
    names, exp = check_cosim_args(args)
    if args.build:
        build_system(args.ssp.parent, name=args.ssp.stem)
        exp = Experiment(exp.stop_time, exp.step, read_experiment(args.ssp).params)
    runners = {"libcosim": run_libcosim, "fmpy": run_fmpy, "fmpy-ssp": run_fmpy_ssp}
    results = [runners[m](args.ssp, step=exp.step, stop_time=exp.stop_time) for m in names]
    qt = [exp.params.get(f"qt_{c}", 1.0 if c == "w" else 0.0) for c in "wxyz"]
    for r in results:
        ang = r.error_angle(qt)
        if v >= 0:
            print(f"{r.master}: {len(r.t) - 1} steps of {r.t[1] - r.t[0]:g} s; angle to target "
                  f"{ang[0]:.6g} -> {ang[-1]:.3g} rad; 2 % settling time {settling_time(r.t, ang):.3f} s")
    if args.plot:
        plot_results(results, args.plot, qt)
        if v >= 0:
            print(args.plot)
    return 0
