"""Empty rosbags messages to fill with the nodes' own ``fill_*`` functions (no ROS).

``new_message("sensor_msgs/msg/Imu")`` gives a Jazzy message with every field zero; the
``fill_*`` functions (``gnss_ins_common.message_fields``, ``gnss_driver.solution.fill_gnss_fix``,
used by the nodes too) set its fields exactly as the nodes do.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

from ins_fusion.bags.typestore import jazzy_typestore

_STRINGS = ("string", "wstring")
#: ROS base types numpy does not name the same way.
_NUMPY_TYPES = {"bool": np.dtype(np.bool_), "byte": np.dtype(np.uint8), "char": np.dtype(np.uint8)}


def new_message(msgtype: str) -> Any:
    """A rosbags message of ``msgtype`` (``pkg/msg/Name``, Jazzy) with every field zero/empty."""
    return _factory(msgtype)()


@cache
def _factory(msgtype: str) -> Callable[[], Any]:
    """Constructor of zero messages of a type (field makers resolved once)."""
    store = jazzy_typestore()
    cls = store.types[msgtype]
    makers = [_zero_factory(kind, detail) for _, (kind, detail) in store.fielddefs[msgtype][1]]
    return lambda: cls(*[make() for make in makers])


def _zero_factory(kind: Nodetype, detail: Any) -> Callable[[], Any]:
    """Maker of the zero value of a field described as the typestore does (kind, detail)."""
    if kind == Nodetype.NAME:
        return _factory(detail)
    if kind == Nodetype.BASE:
        name = detail[0]
        if name in _STRINGS:
            value: object = ""
        else:
            value = 0.0 if name.startswith("float") else (False if name == "bool" else 0)
        return lambda: value
    (element_kind, element), length = detail
    count = length if kind == Nodetype.ARRAY else 0
    if element_kind == Nodetype.BASE and element[0] not in _STRINGS:
        dtype = _NUMPY_TYPES.get(element[0], np.dtype(element[0]))
        return lambda: np.zeros(count, dtype=dtype)
    make = _zero_factory(element_kind, element)
    return lambda: [make() for _ in range(count)]
