"""Message classes from type names, without rosidl_runtime_py (not in the PyPI wheels)."""

import importlib


def message_class(type_name: str) -> type:
    """Class of ``pkg/msg/Type`` (or ``pkg/Type``); ValueError if it is not installed."""
    parts = type_name.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts):
        raise ValueError(f'not a message type name: {type_name!r}')
    package, kind, name = parts
    try:
        module = importlib.import_module(f'{package}.{kind}')
        return getattr(module, name)
    except (ImportError, AttributeError) as err:
        raise ValueError(f'message type {type_name!r} is not installed: {err}') from err
