"""Decoder test material: a team's decode context, well-formed payloads of each kind (:data:`SAMPLES`), their
mutations (a field removed, added, of another type, out of range) and an equality of decode outcomes, shared by
the codec's tests."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from fleet_emu.agents.protocol import MapDelta, MapFill
from fleet_emu.core.codec import Context

CTX = Context(senders=frozenset({"r0", "r1", "r2"}), shape=(4, 5))
ODD = [None, True, False, -1, 0, 1, 3, 19, 20, 2**40, 1.5, "r1", "r9", "", b"x", [], [1], [1, 2], [2, 1], [0, 1],
       [3, 3], [True, 1], {}, {"r1": [1]}, {"r9": [1]}, {"r1": [2, 1]}, {"r1": "1"}, {1: [1]}, list(range(1, 70)),
       {b"r1": [1]}, {"r1": [0]}, {"r1": [True]}, {"r1": [1.0]}, {"r1": [1], "r2": [7]}, {"r1": [1], "r2": []},
       {"r1": [1], "r2": [0]}, {"r1": [2], "r2": [1, 2]}, {"r1": list(range(1, 66))}, {"r1": list(range(1, 65))},
       {"dtype": "int32", "shape": [1], "data": b"\0\0\0\0"}, {"dtype": "int8", "shape": [1], "data": b"\x64"},
       {"dtype": "int32", "shape": [1], "data": b"\xff\xff\xff\xff"}, {"dtype": "int8", "shape": [1], "data": b"\7"},
       {"dtype": "int32", "shape": [2], "data": b"\0\0\0\0"}]


def equal(a: Any, b: Any) -> bool:
    """Two decode outcomes are the same: both rejected (the DecodeError class), or equal records, arrays by dtype
    and value."""
    if isinstance(a, type) or isinstance(b, type):  # DecodeError: both rejected
        return a is b
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.dtype == b.dtype \
            and np.array_equal(a, b)
    if type(a) is not type(b):
        return False
    if hasattr(a, "__struct_fields__"):
        return all(equal(getattr(a, f), getattr(b, f)) for f in a.__struct_fields__)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    return a == b


def mutations(obj: dict) -> list[dict]:
    """``obj`` with each key dropped, and with each key (and an extra one) set to every value of :data:`ODD`."""
    out = []
    for key in [*obj, "extra"]:
        if key in obj:
            drop = dict(obj)
            del drop[key]
            out.append(drop)
        for value in ODD:
            m = copy.deepcopy(obj)
            m[key] = value
            out.append(m)
    return out


SAMPLES = {
    "pose": [{"cell": [1, 2]}, {"cell": [1, 2], "next": [1, 3]}, {"cell": [0, 0], "next": [0, 0], "maps": 4},
             {"cell": [3, 4], "next": [2, 4], "maps": 0, "want": {"r1": [1, 2, 9], "r2": []}}],
    "map": [MapDelta(cells=np.array([0, 19], np.int32), values=np.array([0, 100], np.int8)).fields_obj(),
            MapDelta(cells=np.array([3], np.int32), values=np.array([-1], np.int8), n=5, covers=(1, 4)).fields_obj(),
            MapDelta(cells=np.zeros(0, np.int32), values=np.zeros(0, np.int8), n=1).fields_obj()],
    "mapfill": [MapFill(cells=np.array([0, 19], np.int32), values=np.array([0, 100], np.int8)).fields_obj(),
                MapFill(cells=np.array([3], np.int32), values=np.array([0], np.int8), seqs=(2, 5), upto=9).fields_obj(),
                {"cells": {"dtype": "int32", "shape": [1], "data": b"\1\0\0\0"},
                 "values": {"dtype": "int8", "shape": [1], "data": b"\0"}}],
}
