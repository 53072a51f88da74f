"""The one ``main()`` of a node process: rclpy up, the node made and spun until Ctrl-C or an
external shutdown, then destroyed and rclpy down, whatever happened in between."""

from __future__ import annotations

import sys
from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


def run_node(make_node: Callable[[], Node], args=None, *,
             one_line_errors: tuple[type[BaseException], ...] = (), label: str = '') -> None:
    """Run one node in this process. An exception of ``one_line_errors`` (e.g. the live view's
    port taken) is printed as one line ``[label] error`` and ends the process with code 1; a
    node that refuses its configuration exits by itself (SystemExit 2, params.py)."""
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except one_line_errors as err:
        print(f'[{label}] {err}', file=sys.stderr, flush=True)
        raise SystemExit(1) from None
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
