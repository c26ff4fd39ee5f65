"""The independent CDR peer of the twin's ROS 2 messages (tests/tests/ros2.rs).

Reads from standard input a JSON list of cases, each
{"type": "pkg/msg/Name", "value": {...ROS field names...}, "cdr": "hex"}:
the message's values as the twin wrote them and the CDR bytes the twin
made of them. For each case it writes back, with PyPI rosbags
(`get_typestore(Stores.ROS2_JAZZY)`):
- "cdr": rosbags' own CDR of the same values (hex), to compare byte for byte;
- "decoded": the twin's bytes read back by rosbags, as the same JSON shape;
- "hash": the type's RIHS01 hash as rosbags computes it.
A number that is not finite travels as null both ways (JSON has no NaN).
"""

import json
import math
import sys

import numpy as np
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Nodetype

STORE = get_typestore(Stores.ROS2_JAZZY)
NUMPY = {
    "float64": np.float64, "float32": np.float32, "int8": np.int8, "uint8": np.uint8,
    "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
    "int64": np.int64, "uint64": np.uint64, "byte": np.uint8, "char": np.uint8,
}
FLOATS = ("float32", "float64")


def base_value(kind, value):
    if kind in FLOATS:
        return math.nan if value is None else float(value)
    return value


def build(typename, value):
    """A rosbags message of `typename` from its JSON form."""
    _, fields = STORE.fielddefs[typename]
    return STORE.types[typename](**{n: build_field(d, value[n]) for n, d in fields})


def build_field(desc, value):
    node, detail = desc
    if node == Nodetype.BASE:
        return base_value(detail[0], value)
    if node == Nodetype.NAME:
        return build(detail, value)
    (sub_node, sub_detail), _ = detail
    if sub_node == Nodetype.BASE and sub_detail[0] in NUMPY:
        return np.array([base_value(sub_detail[0], v) for v in value], dtype=NUMPY[sub_detail[0]])
    return [build_field((sub_node, sub_detail), v) for v in value]


def plain(typename, message):
    """The JSON form of a rosbags message of `typename`."""
    _, fields = STORE.fielddefs[typename]
    return {n: plain_field(d, getattr(message, n)) for n, d in fields}


def plain_number(v):
    if isinstance(v, (float, np.floating)):
        v = float(v)
        return v if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def plain_field(desc, value):
    node, detail = desc
    if node == Nodetype.BASE:
        return plain_number(value)
    if node == Nodetype.NAME:
        return plain(detail, value)
    sub = detail[0]
    return [plain_field(sub, v) for v in value]


def main():
    out = []
    for case in json.load(sys.stdin):
        typename = case["type"]
        ours = STORE.serialize_cdr(build(typename, case["value"]), typename)
        theirs = STORE.deserialize_cdr(bytes.fromhex(case["cdr"]), typename)
        out.append({
            "cdr": bytes(ours).hex(),
            "decoded": plain(typename, theirs),
            "hash": STORE.hash_rihs01(typename),
        })
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
