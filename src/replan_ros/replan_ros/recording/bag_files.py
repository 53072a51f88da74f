"""Which .mcap files make a bag: a file alone, or a bag directory's files (splits) in name
order. ``X.mcap`` is left out once ``X.recovered.mcap`` is beside it: the copy replaces it, and
reading both would give every message twice. The one rule for the directory's
``metadata.yaml`` (``bag_dir``), the readers (``bag_read``, ``bag_open``) and the recorder."""

from __future__ import annotations

from pathlib import Path

RECOVERED_SUFFIX = '.recovered.mcap'


def recovered_name(path: Path) -> Path:
    """Where the recovered copy of ``path`` goes: ``X.mcap`` -> ``X.recovered.mcap``."""
    return path.with_name(path.stem + RECOVERED_SUFFIX)


def replaced(name: str, names: set[str] | list[str]) -> bool:
    """True if ``name`` (an .mcap file name) has its recovered copy among ``names``."""
    return (not name.endswith(RECOVERED_SUFFIX)
            and name[:-len('.mcap')] + RECOVERED_SUFFIX in names)


def bag_files(bag: str | Path) -> list[Path]:
    """The files of ``bag`` in playback order: ``bag`` itself if it is a file, else the
    directory's .mcap files by name (the recorder names its splits by their start time), each
    killed file's recovered copy in its place."""
    bag = Path(bag)
    if bag.is_file():
        return [bag]
    names = sorted(p.name for p in bag.glob('*.mcap') if p.is_file())
    return [bag / name for name in names if not replaced(name, names)]
