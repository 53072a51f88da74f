"""``package://`` names of the robot models' files, the one place that resolves them.

A URDF names its meshes ``package://PACKAGE/PATH``. ``package_file`` finds the folder of
PACKAGE (a name given with its folder, else a sub-folder of that name in one of the search
folders, as ROS_PACKAGE_PATH's folders are searched) and returns PACKAGE's folder / PATH.
Packages are found by folder name, not by a ``package.xml``: example-robot-data's
``package.xml`` calls it ``example_robot_descriptions`` while its URDFs say
``example-robot-data``.

``ModelAssets`` serves such names to viewers (the live view's asset fetch): only files under
its allowed roots, whatever the URI says (``..``, symlinks). ``served_model_assets`` gives the
project's: example-robot-data's share tree and the project's ``urdf/`` folder.

ROS-free.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from replan_core.robot.robot_file import example_robot_data_dir

PACKAGE_SCHEME = 'package://'
PROJECT_PACKAGE = 'replan_ros'      # installs urdf/ under share/replan_ros, as ROS finds it
ROBOT_DATA_PACKAGE = 'example-robot-data'


class AssetError(ValueError):
    """A URI that does not name a served file; the message says why."""


def split_package_uri(uri: str) -> tuple[str, str]:
    """``(PACKAGE, PATH)`` of ``package://PACKAGE/PATH``; AssetError if it is not one, or if
    PATH could leave the package (``..``, an absolute path)."""
    if not uri.startswith(PACKAGE_SCHEME):
        raise AssetError(f'{uri!r}: only {PACKAGE_SCHEME} URIs name model files')
    package, _, relative = uri[len(PACKAGE_SCHEME):].partition('/')
    if not package or not relative:
        raise AssetError(f'{uri!r}: expected {PACKAGE_SCHEME}PACKAGE/PATH')
    parts = relative.split('/')
    # Checked on the name, before any file system call: a name that climbs is refused even
    # where the folder it would reach is allowed.
    if any(part in ('', '.', '..') for part in parts) or '\\' in relative or '\0' in uri:
        raise AssetError(f'{uri!r}: the path must stay inside its package '
                         '(no "..", ".", empty or absolute parts)')
    return package, relative


def package_file(uri: str, search: Iterable[Path],
                 named: Mapping[str, Path] | None = None) -> Path:
    """The file ``uri`` names (not checked to exist): its package's folder / PATH, the package
    taken from ``named`` or else the first ``folder / PACKAGE`` of ``search`` that is a
    folder. AssetError for a URI that is not ``package://`` or names an unknown package."""
    package, relative = split_package_uri(uri)
    folder = (named or {}).get(package)
    if folder is None:
        folder = next((d / package for d in search if (d / package).is_dir()), None)
    if folder is None:
        raise AssetError(f'{uri!r}: unknown package {package!r}')
    return folder / relative


@dataclass(frozen=True)
class ModelAssets:
    """Files that viewers may fetch by ``package://`` name: those under ``roots`` only."""

    roots: tuple[Path, ...]                  # every served file lies under one of these
    search: tuple[Path, ...] = ()            # folders whose sub-folders are packages
    named: Mapping[str, Path] = field(default_factory=dict)   # package -> its folder

    def path(self, uri: str) -> Path:
        """The served file of ``uri`` (symlinks resolved); AssetError if there is none."""
        candidate = package_file(uri, self.search, self.named)
        try:
            real = candidate.resolve()
        except (OSError, RuntimeError) as err:           # a symlink loop
            raise AssetError(f'{uri!r}: cannot resolve ({err})') from None
        if not any(real.is_relative_to(root.resolve()) for root in self.roots):
            raise AssetError(f'{uri!r}: outside the served model folders')
        if not real.is_file():
            raise AssetError(f'{uri!r}: no such file')
        return real

    def read(self, uri: str) -> bytes:
        """The bytes of the file ``uri`` names; AssetError if it is not served."""
        path = self.path(uri)
        try:
            return path.read_bytes()
        except OSError as err:
            raise AssetError(f'{uri!r}: cannot read ({err.strerror})') from None


def served_model_assets(project_root: Path) -> ModelAssets:
    """The project's model files: ``package://replan_ros/urdf/...`` (the project's ``urdf/``)
    and example-robot-data's share tree, as its URDFs name it (``package://example-robot-data/
    robots/...``, or ``package://<robot>_description/...``), if it is installed."""
    project_root = Path(project_root)
    roots = [project_root / 'urdf']
    named = {PROJECT_PACKAGE: project_root}
    search: list[Path] = []
    try:
        robots = example_robot_data_dir()
    except FileNotFoundError:
        robots = None
    if robots is not None:
        roots.append(robots.parent)
        named[ROBOT_DATA_PACKAGE] = robots.parent
        search.append(robots)
    return ModelAssets(tuple(roots), tuple(search), named)
