"""Building `diagnostic_msgs/DiagnosticArray` messages from plain values."""

from collections.abc import Mapping

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR
STALE = DiagnosticStatus.STALE


def _format(value: object) -> str:
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)


def status(name: str, level: bytes | int, message: str,
           values: Mapping[str, object] | None = None, hardware_id: str = '') -> DiagnosticStatus:
    """One status entry; ``values`` become key/value pairs (floats with 6 significant digits)."""
    lvl = level if isinstance(level, bytes) else bytes([level])
    return DiagnosticStatus(
        level=lvl, name=name, message=message, hardware_id=hardware_id,
        values=[KeyValue(key=str(k), value=_format(v)) for k, v in (values or {}).items()])


def array(stamp: Time, *statuses: DiagnosticStatus) -> DiagnosticArray:
    msg = DiagnosticArray()
    msg.header.stamp = stamp
    msg.status = list(statuses)
    return msg


def values_of(diag_status: DiagnosticStatus) -> dict[str, str]:
    """Key/value pairs of a status as a dict (for tests and tools)."""
    return {kv.key: kv.value for kv in diag_status.values}
