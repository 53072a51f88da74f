"""sensor_msgs/PointCloud2 as a typed table (a numpy structured array): the layout of every table
topic (contacts, contact_events, footholds).

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import functools

import numpy as np
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

_NUMPY_OF_FIELD = {PointField.INT8: 'i1', PointField.UINT8: 'u1', PointField.INT16: '<i2',
                   PointField.UINT16: '<u2', PointField.INT32: '<i4', PointField.UINT32: '<u4',
                   PointField.FLOAT32: '<f4', PointField.FLOAT64: '<f8'}


_FIELD_OF_NUMPY = {np.dtype(v).str: k for k, v in _NUMPY_OF_FIELD.items()}


@functools.lru_cache(maxsize=16)
def point_fields(dtype: np.dtype) -> tuple[PointField, ...]:
    """The PointField layout of a table dtype, built once (never modified afterwards)."""
    return tuple(PointField(name=name, offset=dtype.fields[name][1],
                            datatype=_FIELD_OF_NUMPY[dtype.fields[name][0].str], count=1)
                 for name in dtype.names)


def table_to_cloud(hdr: Header, table: np.ndarray) -> PointCloud2:
    """Pack a 1-D numpy structured array (no padding) into a PointCloud2."""
    fields = list(point_fields(table.dtype))
    msg = PointCloud2(header=hdr, height=1, width=len(table), fields=fields,
                      is_bigendian=False, point_step=table.dtype.itemsize,
                      row_step=table.dtype.itemsize * len(table), is_dense=True)
    msg.data = table.tobytes()
    return msg


@functools.lru_cache(maxsize=16)
def _table_dtype(fields: tuple[tuple[str, int, int], ...], itemsize: int) -> np.dtype:
    """The numpy dtype of a PointCloud2 layout; a few layouts recur at every message."""
    return np.dtype({'names': [name for name, _, _ in fields],
                     'formats': [_NUMPY_OF_FIELD[datatype] for _, datatype, _ in fields],
                     'offsets': [offset for _, _, offset in fields], 'itemsize': itemsize})


def cloud_to_table(msg: PointCloud2, required: tuple[str, ...] = ()) -> np.ndarray:
    """Unpack a PointCloud2 written by ``table_to_cloud`` (or any little-endian flat one)."""
    if msg.is_bigendian:
        raise ValueError('big-endian PointCloud2 tables are not supported')
    # A malformed layout must give one clear line, not numpy's or a KeyError's words.
    unknown = [f.name for f in msg.fields if f.datatype not in _NUMPY_OF_FIELD or f.count > 1]
    if unknown:
        raise ValueError(f'table fields {unknown} have an unsupported datatype or count')
    try:
        dtype = _table_dtype(tuple((f.name, f.datatype, f.offset) for f in msg.fields),
                             msg.point_step)
    except (ValueError, TypeError) as err:
        raise ValueError(f'table layout does not fit point_step {msg.point_step}: {err}') from None
    missing = [name for name in required if name not in dtype.names]
    if missing:
        raise ValueError(f'table misses fields {missing}')
    count = msg.width * msg.height
    if len(msg.data) < count * msg.point_step:
        raise ValueError(f'table of {count} rows of {msg.point_step} bytes holds only '
                         f'{len(msg.data)} bytes')
    return np.frombuffer(bytes(msg.data), dtype=dtype, count=count)


def require_finite(table: np.ndarray, names: tuple[str, ...], what: str) -> None:
    bad = [name for name in names if not np.all(np.isfinite(table[name]))]
    if bad:
        raise ValueError(f'{what} table holds non-finite {", ".join(bad)}')
