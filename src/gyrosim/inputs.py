"""Time-varying inputs in FMPy's habits: a CSV file or a structured array, and the values applied at a time.

The format is FMPy's (``fmpy.util.read_csv``, ``fmpy.simulate_fmu(input=...)``, ``fmpy simulate --input-file``): a
header row ``time,<input>,<input>,...`` then one row per time, strictly comma-separated; the same as a numpy
structured array with the field ``time`` first and one float field per input.

The values at a time are those ``fmpy.simulation.Input`` applies to a co-simulation FMU before each ``doStep``
(``Input.apply(time, after_event=True)``, FMPy 0.3):

- between two rows: linear interpolation, ``w0 = (t1 - t) / (t1 - t0)``, ``v = w0*v0 + (1 - w0)*v1``;
- before the first row's time and at it: the first row; after the last row's time: the last row (held);
- at a step (two or more rows at the same time, equal within ``math.isclose``): the last of those rows, so the
  step acts from that time on. One quirk of FMPy is kept so that the results agree: a step at the very first time
  applies the *first* row there (its search lands before both rows);
- ``interpolate=False`` is FMPy's handling of a discrete input (and of every non-Real one): zero-order hold, the
  last row at or before ``t``.

:func:`gyrosim.simulate` applies the inputs at the start of every output interval (communication step), at that
step's start time ``start_time + k*output_interval``, and holds them over the step, as ``fmpy.simulate_fmu`` does for
a co-simulation FMU (set the inputs, ``doStep``). FMPy also splits a step at a step of the input that falls inside
it (for FMUs that accept a variable communication step) and records an extra row there; gyrosim keeps its output
grid and applies such a step from the next output point on: put steps of an input on the output grid.

Every value must be finite and at most :data:`MAX_INPUT` = 1e12 in size, in the input's unit (:func:`input_unit`:
N*m for a torque, ``tau_*`` and ``motor_torque``; N for a force, ``motor_force`` and a ``[[force]]``'s ``f_*``).
The largest torques machines produce are about 1e7 N*m (a large ship's propeller shaft, a wind turbine's main
shaft) and the largest forces about 1e7 N (a rocket engine); 1e12 leaves five orders of magnitude beyond that for
any scene in SI units, while a value such as 1e300 only overflows the state and the work integral at the first step
(a blow-up whose advice would be about max_step). A file's value beyond it is refused with the file, the line, the
column, the value and the range in the input's unit.

Examples
--------
>>> import numpy as np
>>> u = np.array([(0.0, 0.0), (1.0, 2.0), (1.0, 5.0)], dtype=[("time", float), ("tau_z", float)])
>>> s = InputSignal(u)
>>> s.names, s.at(0.25), s.at(1.0), s.at(9.0)
(['tau_z'], {'tau_z': 0.5}, {'tau_z': 5.0}, {'tau_z': 5.0})
"""

from __future__ import annotations

import bisect
import math
from pathlib import Path

import numpy as np

from .errors import ConfigError, name_list

__all__ = ["read_input_csv", "read_input_file", "InputSignal", "input_names", "input_unit", "input_range", "MAX_INPUT"]

_FORMAT = "FMPy's input format: a header row 'time,<input>,...' then one row per time, comma-separated"

#: The largest size of an input value, in the input's unit (N*m for a torque, N for a force); see the module's notes.
MAX_INPUT = 1e12


def input_unit(name: str) -> str:
    """The unit of the input ``name`` (``tau_x``, ``wheel_x.motor_torque``, ``cart.motor_force``,
    ``craft.jet.f_x``): N*m for a torque, N for a force; "its unit" for a name that is neither.

    >>> input_unit("rotor.tau_z"), input_unit("cart.motor_force"), input_unit("jet.f_x")
    ('N*m', 'N', 'N')
    """
    bare = str(name).rpartition(".")[2]
    if bare.startswith("tau_") or bare == "motor_torque":
        return "N*m"
    if bare == "motor_force" or bare in ("f_x", "f_y", "f_z"):
        return "N"
    return "its unit"


def _in_unit(name: str) -> str:
    unit = input_unit(name)
    return "in the input's unit" if unit == "its unit" else f"in {unit}"


def input_range(name: str) -> str:
    """What a value of the input ``name`` may be: ``a finite number from -1e+12 to 1e+12 in N`` (its unit)."""
    return f"a finite number from {-MAX_INPUT:g} to {MAX_INPUT:g} {_in_unit(name)}"


def _isclose(a: float, b: float) -> bool:
    return math.isclose(a, b)  # FMPy's test for "the same time" (rel_tol 1e-9)


def read_input_csv(path, names=None) -> np.ndarray:
    """Read an input file in FMPy's CSV format.

    Parameters
    ----------
    path : str or Path
        A CSV file: a header row with ``time`` first and one name per input (``tau_z``, ``wheel_x.motor_torque``;
        quotes around names are allowed), then one row of numbers per time: time in s, strictly non-decreasing (two
        rows at one time make a step), every value a finite number. Blank lines are skipped.
    names : list of str, optional
        Keep only these inputs, in this order (as ``fmpy.util.read_csv(variable_names=...)``).

    Returns
    -------
    numpy structured array
        Field ``time`` (s) then one float64 field per input, one element per row.

    Raises
    ------
    ConfigError
        The file missing or unreadable, a header without ``time`` first, a missing, empty or repeated name, a row
        with the wrong number of columns, a value that is not a finite number (or an input's beyond
        :data:`MAX_INPUT` in size), time going backwards, no data rows, or a name of ``names`` the file does not
        have. The message names the file, the line and column, the value and what is allowed.

    Examples
    --------
    >>> import tempfile, os
    >>> f = os.path.join(tempfile.mkdtemp(), "u.csv")
    >>> _ = open(f, "w").write("time,tau_z\\n0,0\\n2,1\\n")
    >>> read_input_csv(f)["tau_z"].tolist()
    [0.0, 1.0]
    """
    p = Path(path)
    where = str(path)
    if not p.exists():
        raise ConfigError("input file", where, "an existing CSV file (" + _FORMAT + "); it was not found")
    if p.is_dir():
        raise ConfigError("input file", where, "a CSV file (" + _FORMAT + "); it is a folder")
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise ConfigError("input file", where, f"a readable CSV file; it cannot be read: {e.strerror or e}") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise ConfigError("input file", where, f"a text (UTF-8) CSV file; byte {e.start} is {raw[e.start]:#04x}, "
                          "which is not text") from None
    lines = text.splitlines()
    header_at = next((i for i, line in enumerate(lines) if line.strip()), None)
    if header_at is None:
        raise ConfigError("input file", where, f"{_FORMAT}; the file is empty")
    header = [c.strip().strip('"').strip("'").strip() for c in lines[header_at].split(",")]
    hline = header_at + 1
    if header[0] != "time":
        hint = " (the file looks semicolon- or tab-separated)" if (";" in header[0] or "\t" in header[0]) else ""
        raise ConfigError("first column", header[0], f"'time' ({_FORMAT}){hint}", where=f"{where}, line {hline}")
    if len(header) < 2:
        raise ConfigError("header", lines[header_at].strip(), f"'time' then at least one input name ({_FORMAT})",
                          where=f"{where}, line {hline}")
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        if not name:
            raise ConfigError(f"name of column {j + 1}", name, "a variable name (the header has an empty name)",
                              where=f"{where}, line {hline}")
        if name in seen:
            raise ConfigError(f"name of column {j + 1}", name, f"a name not used before (column {seen[name] + 1} "
                              "has it already)", where=f"{where}, line {hline}")
        seen[name] = j
    ncol = len(header)
    rows: list[list[float]] = []
    line_of: list[int] = []
    for i in range(header_at + 1, len(lines)):
        line = lines[i]
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != ncol:
            raise ConfigError("row", line.strip()[:80], f"{ncol} comma-separated values, one per column of the header "
                              f"({', '.join(header[:8])}{', ...' if ncol > 8 else ''}); it has {len(cells)}",
                              where=f"{where}, line {i + 1}")
        row = []
        for j, cell in enumerate(cells):
            literal = cell.strip()
            try:
                x = float(literal)
            except ValueError:
                x = None
            if x is None or not math.isfinite(x):
                unit = "in s" if j == 0 else _in_unit(header[j])
                raise ConfigError(header[j], literal, f"a finite number {unit}",
                                  where=f"{where}, line {i + 1}, column {j + 1}")
            if j and abs(x) > MAX_INPUT:
                raise ConfigError(header[j], literal, input_range(header[j]),
                                  where=f"{where}, line {i + 1}, column {j + 1}")
            row.append(x)
        if rows and row[0] < rows[-1][0]:
            raise ConfigError("time", cell_text(lines[i]), f"a time >= {rows[-1][0]!r} s, the time of line "
                              f"{line_of[-1]} (time must not decrease; two rows at one time make a step)",
                              where=f"{where}, line {i + 1}, column 1")
        rows.append(row)
        line_of.append(i + 1)
    if not rows:
        raise ConfigError("input file", where, f"{_FORMAT}; it has a header and no data rows")
    arr = np.array([tuple(r) for r in rows], dtype=[(n, np.float64) for n in header])
    if names is not None:
        names = list(names)
        from .scene import did_you_mean

        for n in names:
            if n not in seen or n == "time":
                raise ConfigError("input", n, f"a column of {where}{did_you_mean(n, header[1:])}: "
                                  + ", ".join(header[1:]))
        arr = _select(arr, names)
    return arr


def read_input_file(path, names=None) -> InputSignal:
    """:func:`read_input_csv`, as an :class:`InputSignal` that remembers where each column came from: a name that
    is not an input of the model (:meth:`InputSignal.check_against`) is then named with the file, the header's line
    and the column's number."""
    arr = read_input_csv(path, names)
    lines = Path(path).read_bytes().decode("utf-8-sig").splitlines()
    hline = next(i for i, line in enumerate(lines) if line.strip()) + 1
    header = [c.strip().strip('"').strip("'").strip() for c in lines[hline - 1].split(",")]
    sig = InputSignal(arr)
    sig.origin = {n: f"{path}, line {hline}, column {header.index(n) + 1}" for n in sig.names}
    return sig


def cell_text(line: str) -> str:
    """The first cell of a CSV line, stripped (the time literal, for messages)."""
    return line.split(",", 1)[0].strip()


def _select(arr: np.ndarray, names: list[str]) -> np.ndarray:
    out = np.empty(arr.shape, dtype=[("time", np.float64)] + [(n, np.float64) for n in names])
    for n in ("time", *names):
        out[n] = arr[n]
    return out


def input_names(model) -> list[str]:
    """The input variables of ``model`` as an input array names them: ``tau_x..tau_z`` for one body,
    ``<body>.tau_x..`` in a scene of several bodies, ``<body>.motor_torque`` and ``<body>.tau_*`` in a tree."""
    return model.input_names


class InputSignal:
    """Input values over time, as FMPy applies them (see the module's notes).

    Parameters
    ----------
    array : numpy structured array
        Field ``time`` first (s, finite, non-decreasing), then one numeric field per input (finite values), at
        least one row; as ``fmpy.simulate_fmu(input=...)`` takes it.
    names : list of str, optional
        The inputs to use, in order (default: every field after ``time``).
    interpolate : bool
        True (FMPy's handling of a continuous Real input, every input of gyrosim): linear between rows. False
        (FMPy's handling of a discrete input): zero-order hold, the last row at or before the time.

    Attributes
    ----------
    names : list of str
        The inputs, in order.
    time : (n,) ndarray
        The rows' times, s.
    values : (n, len(names)) ndarray
        The rows' values.

    Raises
    ------
    ConfigError
        Not a structured array, no ``time`` field first, an unknown name, a field that is not a numeric scalar, a
        non-finite value or time going backwards (naming the row), or no rows.
    """

    def __init__(self, array, names=None, *, interpolate: bool = True):
        if isinstance(array, InputSignal):
            array = array.array
        if not (isinstance(array, np.ndarray) and array.dtype.names):
            raise ConfigError("input", type(array).__name__, "a numpy structured array with the field 'time' first "
                              "and one field per input, as fmpy.simulate_fmu(input=...) takes it "
                              "(gyrosim.inputs.read_input_csv reads one from a CSV file)")
        fields = list(array.dtype.names)
        if fields[0] != "time":
            raise ConfigError("input's first field", fields[0], "'time' (s), then one field per input")
        arr = array.reshape(-1)
        if arr.size == 0:
            raise ConfigError("input", "an array of 0 rows", "at least one row (time, values)")
        if names is None:
            names = fields[1:]
        else:
            if isinstance(names, str):
                names = [names]
            names = list(names)
            from .scene import did_you_mean

            for n in names:
                if n not in fields[1:]:
                    raise ConfigError("input", n, f"a field of the input array{did_you_mean(n, fields[1:])}: "
                                      + ", ".join(fields[1:]))
        if not names:
            raise ConfigError("input", "an array with only 'time'", "'time' and at least one input field")
        for n in ("time", *names):
            dt = arr.dtype[n]
            if dt.shape != () or dt.kind not in "fiub":
                raise ConfigError(f"input field {n!r}", str(dt), "a scalar number field (float, int or bool)")
        t = np.asarray(arr["time"], dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            i = int(bad[0])
            raise ConfigError("time", float(t[i]), "a finite number in s", where=f"input row {i}")
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            i = int(back[0]) + 1
            raise ConfigError("time", float(t[i]), f"a time >= {float(t[i - 1])!r} s, the time of row {i - 1} (time "
                              "must not decrease; two rows at one time make a step)", where=f"input row {i}")
        values = np.empty((arr.size, len(names)))
        for j, n in enumerate(names):
            v = np.asarray(arr[n], dtype=np.float64)
            bad = np.flatnonzero(~np.isfinite(v))
            if bad.size:
                i = int(bad[0])
                raise ConfigError(n, float(v[i]), f"a finite number {_in_unit(n)}",
                                  where=f"input row {i} (time {float(t[i])!r} s)")
            big = np.flatnonzero(np.abs(v) > MAX_INPUT)
            if big.size:
                i = int(big[0])
                raise ConfigError(n, float(v[i]), input_range(n), where=f"input row {i} (time {float(t[i])!r} s)")
            values[:, j] = v
        self.array = array
        #: where each input came from (:func:`read_input_file`: "FILE, line L, column C"), for messages
        self.origin: dict[str, str] = {}
        self.names = names
        self.interpolate = bool(interpolate)
        self.time = t
        self.values = values
        self._t = t.tolist()
        self._rows = [tuple(r) for r in values.tolist()]

    def __repr__(self) -> str:
        return (f"InputSignal({len(self._t)} rows from t = {self._t[0]!r} s to {self._t[-1]!r} s: "
                f"{', '.join(self.names)}{'' if self.interpolate else '; held'})")

    def row_at(self, t: float) -> tuple:
        """The values at time ``t`` (s) in the order of :attr:`names` (see :meth:`at`)."""
        tt = self._t
        rows = self._rows
        n = len(tt)
        t = float(t)
        if n < 2:
            return rows[0]
        i0 = bisect.bisect_left(tt, t)  # numpy.searchsorted(t, time), side "left", as FMPy
        if i0 == 0:
            return rows[0]
        if i0 == n:
            return rows[-1]
        if not self.interpolate:  # FMPy's discrete input, after_event=True
            i = i0 - 1
            while i + 1 < n and (tt[i + 1] < t or _isclose(t, tt[i + 1])):
                i += 1
            return rows[i]
        if _isclose(t, tt[i0]) and i0 < n - 1 and _isclose(tt[i0], tt[i0 + 1]):  # a step: the value after it
            while i0 < n - 1 and _isclose(tt[i0], tt[i0 + 1]):
                i0 += 1
            return rows[i0]
        t0, t1 = tt[i0 - 1], tt[i0]
        v0, v1 = rows[i0 - 1], rows[i0]
        w0 = (t1 - t) / (t1 - t0)
        w1 = 1 - w0
        return tuple(w0 * a + w1 * b for a, b in zip(v0, v1))

    def at(self, t: float) -> dict[str, float]:
        """The values FMPy's ``Input.apply(t)`` sets at time ``t`` (s), by input name.

        Linear interpolation between rows, the first row before (and at) the first time, the last row after the
        last; at a step the row after it (``interpolate=False``: the last row at or before ``t``).
        """
        return dict(zip(self.names, self.row_at(t)))

    def table(self, times) -> np.ndarray:
        """The values at each of ``times`` (s): a (len(times), len(names)) array."""
        times = np.asarray(times, dtype=np.float64).reshape(-1)
        out = np.empty((times.size, len(self.names)))
        for k, t in enumerate(times.tolist()):
            out[k] = self.row_at(t)
        return out

    def check_against(self, model) -> list[tuple[str, str, int | str | None]]:
        """Check every name against the inputs of ``model`` (a :class:`~gyrosim.model.Model`).

        Returns
        -------
        list of (name, variable, body)
            How to set each input: ``model.set(variable, value, body=body)``.

        Raises
        ------
        ConfigError
            A name that is not an input of the model's scene, with a "did you mean" and the inputs it has (or how to
            give the scene inputs when it has none).
        """
        from .scene import did_you_mean

        allowed = input_names(model)
        sc = model.scene
        setters = []
        for n in self.names:
            if n not in allowed:
                if not allowed:
                    how = ("give a [[body]] torque_input = true (the inputs tau_x, tau_y, tau_z), a hinge or slider "
                           "motor_input = true (motor_torque, motor_force) or a [[force]] (f_x, f_y, f_z)")
                    raise ConfigError("input", n, f"an input of scene {sc.name!r}, which has none ({how})",
                                      where=self.origin.get(n))
                bare = n.rpartition(".")[2]
                var = model.variables.get(n) or model.variables.get(bare)
                what = ""
                if var is not None and var.causality != "input":
                    role = "a parameter: set it with start_values" if var.causality == "parameter" else "an output"
                    what = f"; {n} is {role}"
                raise ConfigError("input", n, f"an input of scene {sc.name!r}{did_you_mean(n, allowed)}: "
                                  + name_list(allowed, 24) + what, where=self.origin.get(n))
            setters.append((n, n, None))  # the full name: the model finds the body
        return setters
