"""metadata.yaml of a rosbag2 bag (version 9) as ``BagWriter`` writes it."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import yaml

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping, Sequence
    from pathlib import Path

    from rv_te_bench.io._mcap_file import McapFile, TopicInfo
    from rv_te_bench.io._storage import Storage

__all__ = ['bag_info', 'dump_yaml', 'metadata_yaml_bytes', 'qos_profile_dict',
           'replace_metadata_yaml']

_YamlDumper = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)  # libyaml: ~20x faster


def dump_yaml(data: object) -> str:
    """YAML text of plain data, keys in insertion order."""
    return yaml.dump(data, Dumper=_YamlDumper, sort_keys=False)


def qos_profile_dict(
    *,
    reliability: str = 'reliable',
    durability: str = 'volatile',
    history: str = 'keep_last',
    depth: int = 10,
) -> dict[str, Any]:
    """One offered QoS profile in the rosbag2 (metadata version 9) form.

    Args:
        reliability: ``reliable`` or ``best_effort``.
        durability: ``volatile`` or ``transient_local``.
        history: ``keep_last`` or ``keep_all``.
        depth: History depth [messages].

    Returns:
        The dict rosbag2 writes under ``offered_qos_profiles``.
    """
    default = {'sec': 0, 'nsec': 0}  # 0 = the RMW default (infinite)
    return {
        'history': history,
        'depth': int(depth),
        'reliability': reliability,
        'durability': durability,
        'deadline': dict(default),
        'lifespan': dict(default),
        'liveliness': 'automatic',
        'liveliness_lease_duration': dict(default),
        'avoid_ros_namespace_conventions': False,
    }



def bag_info(files: Sequence[McapFile], topics: Iterable[TopicInfo],
             custom_data: Mapping[str, str]) -> dict[str, Any]:
    """``rosbag2_bagfile_information``: counts of the messages on disk, files, custom data."""
    starts = [f.start_ns for f in files if f.message_count]
    ends = [f.end_ns for f in files if f.message_count]
    start = min(starts) if starts else 0
    duration = (max(ends) - start) if ends else 0
    return {
        'version': 9,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(f.message_count for f in files),
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': t.name,
                    'type': t.msgtype,
                    'serialization_format': 'cdr',
                    'offered_qos_profiles': t.qos_list if t.qos_list else [],
                    'type_description_hash': t.digest,
                },
                'message_count': t.count,
            }
            for t in topics
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [f.path.name for f in files],
        'files': [
            {
                'path': f.path.name,
                'starting_time': {
                    'nanoseconds_since_epoch': f.start_ns if f.message_count else 0},
                'duration': {'nanoseconds': (f.end_ns - f.start_ns) if f.message_count else 0},
                'message_count': f.message_count,
            }
            for f in files
        ],
        'custom_data': dict(custom_data),
        'ros_distro': 'jazzy',
    }


def metadata_yaml_bytes(info: Mapping[str, Any]) -> bytes:
    """The text of metadata.yaml for ``rosbag2_bagfile_information`` ``info``, encoded."""
    return dump_yaml({'rosbag2_bagfile_information': dict(info)}).encode()


def replace_metadata_yaml(storage: Storage, folder: Path, data: bytes) -> None:
    """Replace ``folder/metadata.yaml`` atomically (temporary file + rename).

    Raises:
        OSError: It could not be written (the old one stays; the temporary is removed).
    """
    target = folder / 'metadata.yaml'
    tmp = folder / '.metadata.yaml.tmp'
    try:
        storage.write_file(tmp, data)
        storage.replace(tmp, target)
    except OSError:
        try:
            storage.unlink(tmp)
        except OSError:
            pass
        raise
