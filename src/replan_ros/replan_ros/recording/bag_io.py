"""mcap bags in the ROS 2 conventions (what rosbag2_storage_mcap writes and reads), no rosbag2.

- Schemas: encoding ``ros2msg``, name ``pkg/msg/Type``, data = the full ``.msg`` text of the type
  followed by every nested type once (depth first, dependencies in sorted order), each after a
  line of 80 ``=`` and a ``MSG: pkg/Type`` line, exactly as rosbag2's message definition cache
  builds it. The text comes from the installed ``share/<pkg>/msg/<Type>.msg`` files.
- Channels: message encoding ``cdr``; metadata ``offered_qos_profiles`` (YAML list of the
  publishers' QoS, bag metadata version 9 spelling) and ``topic_type_hash`` (RIHS01).
- A ``rosbag2`` metadata record holding ``serialized_metadata`` (version 9), so that
  ``ros2 bag info/play`` parse the QoS strings with the right version.
- Chunked, compressed (zstd or lz4), with message indexes and a summary.

Here: the schemas, the QoS strings and the bag's summary and messages read back; writing and
recovering a bag is ``bag_writer``.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema

PROFILE = 'ros2'
SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
SEPARATOR = '=' * 80
ROS_DISTRO = 'jazzy'
BAG_METADATA_VERSION = 9   # rosbag2 metadata version of Jazzy: QoS policies spelled as strings
MCAP_MAGIC = b'\x89MCAP0\r\n'

_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring'})
# A field line of a .msg file: its type (maybe pkg/Type, maybe with an array suffix), then space.
# Same rule as rosbag2_storage_mcap's MSG_FIELD_TYPE_REGEX; comment lines never match.
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_TYPE_NAME = re.compile(r'^([a-zA-Z][a-zA-Z0-9_]*)/(?:msg/)?([a-zA-Z][a-zA-Z0-9_]*)$')


# ----------------------------------------------------------------------------- schemas

def interface_share_dir(package: str) -> Path:
    """``share/<package>`` of an installed interface package.

    Looked up in the ament index (AMENT_PREFIX_PATH) first; the ROS wheels install their index
    under the venv prefix (``sys.prefix``), which env.sh does not put on AMENT_PREFIX_PATH, so
    that prefix is searched too.
    """
    try:
        return Path(get_package_share_directory(package))
    except PackageNotFoundError:
        marker = Path(sys.prefix, 'share', 'ament_index', 'resource_index', 'packages', package)
        if marker.exists():
            return Path(sys.prefix, 'share', package)
        raise


def split_type_name(type_name: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (pkg, Type)."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(f'not a message type name: {type_name!r}')
    return match.group(1), match.group(2)


# Definitions of types that the PyPI wheels do not install but the bags carry, verbatim from
# Jazzy's interface packages: /tf (tf2_msgs/TFMessage) is written from its schema text and
# CDR-encoded without a Python class (state_view.py). Installed files take precedence.
EXTRA_DEFINITIONS = {
    ('tf2_msgs', 'TFMessage'): 'geometry_msgs/TransformStamped[] transforms\n',
}


def _msg_text(package: str, name: str) -> str:
    try:
        path = interface_share_dir(package) / 'msg' / f'{name}.msg'
    except PackageNotFoundError:
        if (package, name) in EXTRA_DEFINITIONS:
            return EXTRA_DEFINITIONS[(package, name)]
        raise FileNotFoundError(f'interface package {package} is not installed') from None
    if not path.is_file():
        if (package, name) in EXTRA_DEFINITIONS:
            return EXTRA_DEFINITIONS[(package, name)]
        raise FileNotFoundError(f'no interface definition {path}')
    return path.read_text()


def _dependencies(text: str, package: str) -> list[str]:
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(deps)


def message_definition(type_name: str) -> str:
    """Full ``ros2msg`` definition of ``type_name``: its .msg text plus all nested types."""
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise RecursionError(f'message definition of {type_name} nests too deep')
        package, short = split_type_name(name)
        text = _msg_text(package, short)
        out = text
        for dep in _dependencies(text, package):
            if dep not in seen:
                seen.add(dep)
                out += f'\n{SEPARATOR}\nMSG: {dep}\n' + append(dep, depth - 1)
        return out

    return append(type_name, 50)


def normalize_type_name(type_name: str) -> str:
    package, short = split_type_name(type_name)
    return f'{package}/msg/{short}'


def has_header(type_name: str) -> bool:
    """True if the first field of the type is a ``std_msgs/Header`` (its stamp then leads the
    CDR payload)."""
    package, short = split_type_name(type_name)
    for line in _msg_text(package, short).splitlines():
        line = line.split('#', 1)[0].strip()
        if not line or '=' in line:   # blank, comment or constant ("uint8 NAME=1")
            continue
        field_type = line.split()[0]
        return field_type == 'std_msgs/Header' or (package == 'std_msgs'
                                                   and field_type == 'Header')
    return False


# ----------------------------------------------------------------------------- QoS

def _duration_yaml(duration) -> dict:
    nanoseconds = duration.nanoseconds
    return {'sec': nanoseconds // 1_000_000_000, 'nsec': nanoseconds % 1_000_000_000}


def qos_to_dict(qos) -> dict:
    """An rclpy ``QoSProfile`` as rosbag2 writes it (metadata version 9: policies as strings)."""
    return {
        'history': qos.history.name.lower(),
        'depth': int(qos.depth),
        'reliability': qos.reliability.name.lower(),
        'durability': qos.durability.name.lower(),
        'deadline': _duration_yaml(qos.deadline),
        'lifespan': _duration_yaml(qos.lifespan),
        'liveliness': qos.liveliness.name.lower(),
        'liveliness_lease_duration': _duration_yaml(qos.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(qos.avoid_ros_namespace_conventions),
    }


def qos_profiles_yaml(profiles: Iterable) -> str:
    """``offered_qos_profiles`` channel metadata: a YAML list of the publishers' profiles."""
    return yaml.safe_dump([qos_to_dict(p) for p in profiles], sort_keys=False,
                          default_flow_style=False)


_POLICY_INTS = {   # metadata version <= 8 wrote the rmw enum values
    'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all'},
    'reliability': {0: 'system_default', 1: 'reliable', 2: 'best_effort'},
    'durability': {0: 'system_default', 1: 'transient_local', 2: 'volatile'},
    'liveliness': {0: 'system_default', 1: 'automatic', 3: 'manual_by_topic'},
}


def qos_from_yaml(text: str):
    """First profile of an ``offered_qos_profiles`` string as an rclpy ``QoSProfile``
    (None if there is none). Accepts both the string (v9) and the integer (v8) spellings."""
    from rclpy.duration import Duration
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        LivelinessPolicy,
        QoSProfile,
        ReliabilityPolicy,
    )
    try:
        profiles = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return None
    if not profiles or not isinstance(profiles, list) or not isinstance(profiles[0], dict):
        return None
    raw = profiles[0]

    def policy(key: str, enum):
        value = raw.get(key, 'system_default')
        if isinstance(value, int):
            value = _POLICY_INTS[key].get(value, 'system_default')
        try:
            return enum[str(value).upper()]
        except KeyError:
            return enum.SYSTEM_DEFAULT

    def duration(key: str):
        value = raw.get(key) or {}
        ns = int(value.get('sec', 0)) * 1_000_000_000 + int(value.get('nsec', 0))
        # Infinite (and the Foxy-era infinities) map to "unspecified", which rmw accepts.
        return Duration(nanoseconds=0 if ns >= 0x7FFFFFFF * 1_000_000_000 else ns)

    history = policy('history', HistoryPolicy)
    depth = int(raw.get('depth', 10)) or 10
    return QoSProfile(
        history=history if history != HistoryPolicy.SYSTEM_DEFAULT else HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=policy('reliability', ReliabilityPolicy),
        durability=policy('durability', DurabilityPolicy),
        liveliness=policy('liveliness', LivelinessPolicy),
        deadline=duration('deadline'),
        lifespan=duration('lifespan'),
        liveliness_lease_duration=duration('liveliness_lease_duration'))


def rosbag2_metadata(file_name: str) -> dict[str, str]:
    """The ``rosbag2`` metadata record: tells rosbag2 which metadata version the channel
    metadata follows. Counts and times are left zero: rosbag2 takes them from the summary."""
    info = {
        'version': BAG_METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': 0},
        'starting_time': {'nanoseconds_since_epoch': 0},
        'message_count': 0,
        'topics_with_message_count': [],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [],
        'custom_data': {},
        'ros_distro': ROS_DISTRO,
    }
    return {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)}


# ----------------------------------------------------------------------------- reading

@dataclass
class TopicInfo:
    topic: str
    type_name: str
    offered_qos_profiles: str
    message_count: int = 0
    type_hash: str = ''


@dataclass
class BagSummary:
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    message_count: int = 0
    start_ns: int = 0
    end_ns: int = 0
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    profile: str = ''
    library: str = ''


def summarize(path: str | Path) -> BagSummary:
    """Topics, counts, time range and metadata of a finished bag (uses its summary)."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        header = reader.get_header()
        summary = reader.get_summary()
        if summary is None:
            raise McapError(f'{path} has no summary: recover it first (bag_recover)')
        out = BagSummary(profile=header.profile, library=header.library)
        stats = summary.statistics
        counts = stats.channel_message_counts if stats else {}
        for cid, channel in summary.channels.items():
            schema = summary.schemas.get(channel.schema_id)
            out.topics[channel.topic] = TopicInfo(
                topic=channel.topic, type_name=schema.name if schema else '',
                offered_qos_profiles=channel.metadata.get('offered_qos_profiles', ''),
                message_count=counts.get(cid, 0),
                type_hash=channel.metadata.get('topic_type_hash', ''))
        if stats:
            out.message_count = stats.message_count
            out.start_ns, out.end_ns = stats.message_start_time, stats.message_end_time
        for record in reader.iter_metadata():
            out.metadata[record.name] = dict(record.metadata)
    return out


def iter_raw(path: str | Path, topics: Iterable[str] | None = None
             ) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """(schema, channel, message) in log-time order, payloads left serialized."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        yield from reader.iter_messages(topics=list(topics) if topics else None,
                                        log_time_order=True)


def iter_decoded(path: str | Path, topics: Iterable[str] | None = None):
    """(topic, log_time, publish_time, decoded message) with mcap_ros2's own CDR decoder, which
    parses the schema text (so this checks the schemas too)."""
    from mcap_ros2.decoder import DecoderFactory
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=list(topics) if topics else None, log_time_order=True):
            yield channel.topic, message.log_time, message.publish_time, decoded


def check_bag(path: str | Path) -> int:
    """Read every message of a bag once (chunk CRCs checked) before a tool uses it; returns
    the message count. A truncated or corrupt file raises ``McapError`` with one line saying
    what is wrong, whatever the mcap library raised (a corrupt chunk can surface as a KeyError
    or a decompression error deep in it, which would otherwise end the tool with a traceback).
    """
    count = 0
    try:
        with open(path, 'rb') as stream:
            reader = make_reader(stream, validate_crcs=True)
            if reader.get_summary() is None:
                raise McapError('no summary (its recorder was killed?)')
            for _ in reader.iter_messages():
                count += 1
    except OSError:
        raise
    except Exception as err:        # any library error: one line, not a traceback
        what = str(err).splitlines()[0] if str(err) else ''
        raise McapError(f'corrupt or truncated after {count} readable messages '
                        f'({type(err).__name__}{": " + what if what else ""})') from None
    return count
