"""ROS 2 type hashes (RIHS01, REP 2011) of the message definitions this package ships.

rmw_zenoh (Jazzy and later) names every topic's Zenoh key and liveliness token by its type's hash, so a ROS 2
node matches our publishers only when the hash is the one its own type support computes. The hash is computed
here from the ``ros2msg`` definitions of :mod:`gyrosim.telemetry.messages` the way rosidl does
(``rosidl_generator_type_description.calculate_type_hash``): the type's description (its fields with their type
ids, capacities and nested type names; no default values, no constants, no comments) and those of every type it
references, sorted by name, as JSON with ``", "`` and ``": "`` separators, hashed with SHA-256; the hash is
``"RIHS01_"`` and the digest in hex. The tests hold the results to the hashes ROS 2 publishes for these types and
to an independent implementation (rosbags).
"""

from __future__ import annotations

import hashlib
import json
import re
from functools import cache

__all__ = ["type_hash", "type_description"]

#: rosidl's type ids (type_description_interfaces/msg/FieldType); arrays add 48 (fixed size), 96 (bounded sequence)
#: or 144 (unbounded sequence) to the element's id.
_PRIMITIVE_IDS = {"int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8, "uint64": 9,
                  "float32": 10, "float64": 11, "char": 13, "wchar": 14, "bool": 15, "byte": 16, "string": 17,
                  "wstring": 18}
_NESTED = 1
_BOUNDED_STRING = {"string": 21, "wstring": 22}
_FIXED_ARRAY, _BOUNDED_SEQUENCE, _UNBOUNDED_SEQUENCE = 48, 96, 144

_FIELD = re.compile(r"^(?P<type>[A-Za-z_][\w/]*)(?P<bound><=\d+)?(?P<array>\[(?P<size>(?:<=)?\d*)\])?\s+"
                    r"(?P<name>[A-Za-z_]\w*)(?P<rest>.*)$")


def _full_name(name: str, package: str) -> str:
    """``pkg/Name`` or ``pkg/msg/Name`` (or ``Name`` in ``package``) as ``pkg/msg/Name``."""
    parts = name.split("/")
    if len(parts) == 1:
        return f"{package}/msg/{parts[0]}"
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


def _sections(type_name: str, text: str) -> dict[str, str]:
    """The concatenated definition split into one text per type (``pkg/msg/Name`` -> its fields)."""
    chunks = re.split(r"^=+\n", text, flags=re.M)
    out = {type_name: chunks[0]}
    for chunk in chunks[1:]:
        head, _, body = chunk.partition("\n")
        if not head.startswith("MSG: "):
            raise ValueError(f"a section of {type_name}'s definition starts with {head!r}, not 'MSG: pkg/Name'")
        out[_full_name(head[5:].strip(), "")] = body
    return out


def _fields(type_name: str, body: str) -> list[dict]:
    package = type_name.split("/")[0]
    fields = []
    for line in body.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = _FIELD.match(line)
        if m is None:
            raise ValueError(f"cannot read the field {line!r} of {type_name}")
        if m["rest"].lstrip().startswith("="):  # a constant, not a field
            continue
        base, bound = m["type"], m["bound"]
        if base in _PRIMITIVE_IDS:
            nested = ""
            type_id = _BOUNDED_STRING[base] if bound else _PRIMITIVE_IDS[base]
        else:
            nested = _full_name(base, package)
            type_id = _NESTED
        capacity = 0
        if m["array"] is not None:
            size = m["size"]
            if size == "":
                type_id += _UNBOUNDED_SEQUENCE
            elif size.startswith("<="):
                type_id += _BOUNDED_SEQUENCE
                capacity = int(size[2:])
            else:
                type_id += _FIXED_ARRAY
                capacity = int(size)
        fields.append({"name": m["name"], "type": {"type_id": type_id, "capacity": capacity,
                                                   "string_capacity": int(bound[2:]) if bound else 0,
                                                   "nested_type_name": nested}})
    if not fields:  # rosidl gives an empty message one member
        fields.append({"name": "structure_needs_at_least_one_member",
                       "type": {"type_id": 3, "capacity": 0, "string_capacity": 0, "nested_type_name": ""}})
    return fields


def type_description(type_name: str, text: str) -> dict:
    """The REP 2011 description of ``type_name`` from its concatenated ``ros2msg`` definition ``text``:
    ``{"type_description": ..., "referenced_type_descriptions": [...]}`` (references sorted by name)."""
    sections = _sections(type_name, text)
    described = {name: {"type_name": name, "fields": _fields(name, body)} for name, body in sections.items()}
    seen, todo = set(), [type_name]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        if name not in described:
            raise ValueError(f"{type_name}'s definition references {name}, which it does not define")
        seen.add(name)
        todo += [f["type"]["nested_type_name"] for f in described[name]["fields"] if f["type"]["nested_type_name"]]
    refs = sorted(seen - {type_name})
    return {"type_description": described[type_name], "referenced_type_descriptions": [described[r] for r in refs]}


@cache
def type_hash(type_name: str, text: str | None = None) -> str:
    """``RIHS01_<sha256 hex>`` of ``type_name`` (``pkg/msg/Name``) from its definition (default: the one
    :mod:`gyrosim.telemetry.messages` publishes)."""
    if text is None:
        from .messages import msgdef

        text = msgdef(type_name)
    desc = json.dumps(type_description(type_name, text), separators=(", ", ": "), sort_keys=False,
                      ensure_ascii=True)
    return "RIHS01_" + hashlib.sha256(desc.encode("utf-8")).hexdigest()
