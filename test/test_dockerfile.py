"""docker/Dockerfile's structure, read without Docker (no engine on the development machines)."""

from __future__ import annotations

import json
import re

import pytest
from harness import REPO_ROOT

DOCKERFILE = REPO_ROOT / 'docker' / 'Dockerfile'
SETUP_SH = REPO_ROOT / 'scripts' / 'setup.sh'


def instructions() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) in order; continuation lines joined, comments dropped."""
    result, pending = [], ''
    for line in DOCKERFILE.read_text().splitlines():
        if not pending and (not line.strip() or line.lstrip().startswith('#')):
            continue
        if line.rstrip().endswith('\\'):
            pending += line.rstrip()[:-1] + ' '
            continue
        text = (pending + line).strip()
        pending = ''
        keyword, _, args = text.partition(' ')
        result.append((keyword.upper(), ' '.join(args.split())))
    return result


def index_of(predicate) -> int:
    return next(i for i, item in enumerate(instructions()) if predicate(*item))


def setup_flags() -> set[str]:
    """The options in setup.sh's argument loop (`-h|--help)`, `--deps-only)`; not `*)`)."""
    text = SETUP_SH.read_text()
    loop = text[text.index('case "$1" in'):text.index('esac')]
    patterns = re.findall(r'^\s*(-[^)\s]*)\)', loop, re.MULTILINE)
    return {flag for pattern in patterns for flag in pattern.split('|')}


def test_set_up_is_exactly_setup_sh():
    runs = [args for keyword, args in instructions() if keyword == 'RUN']
    setups = [args for args in runs if 'setup.sh' in args]
    assert setups, 'no RUN of scripts/setup.sh'
    for args in setups:
        command, *flags = args.split()
        assert command == './scripts/setup.sh', args
        assert set(flags) <= setup_flags(), f'{args}: setup.sh has no such option'
    # The last one is setup.sh as a fresh machine runs it: no flags.
    assert setups[-1] == './scripts/setup.sh'
    # Nothing installs Python packages or builds behind setup.sh's back.
    for args in runs:
        assert not re.search(r'\b(pip|colcon|venv|ensurepip)\b', args), args


def test_requirements_before_sources_and_wheels_before_build():
    steps = instructions()
    copy_requirements = index_of(lambda k, a: k == 'COPY' and 'requirements.txt' in a.split())
    copy_setup = index_of(lambda k, a: k == 'COPY' and 'scripts/setup.sh' in a.split())
    deps = index_of(lambda k, a: k == 'RUN' and a.startswith('./scripts/setup.sh --deps-only'))
    sources = index_of(lambda k, a: k == 'COPY' and a.split()[-2:] == ['.', '.'])
    build = index_of(lambda k, a: k == 'RUN' and a == './scripts/setup.sh')
    assert copy_requirements < deps and copy_setup < deps < sources < build, steps
    # Only the pins and the script before the wheels' layer, or every edit reinstalls them.
    for keyword, args in steps[:deps]:
        if keyword == 'COPY':
            sources_copied = [a for a in args.split() if not a.startswith('--')][:-1]
            assert set(sources_copied) <= {'requirements.txt', 'requirements-ray.txt',
                                           'scripts/setup.sh'}, args


def test_the_image_has_what_the_test_suite_sets_up():
    """scripts/test.sh sets up with Ray (test/test_ray.py): the image installs it too, so
    `docker run IMAGE ./scripts/test.sh` installs nothing, and the image can be a Ray node."""
    test_sh = (REPO_ROOT / 'scripts' / 'test.sh').read_text()
    wanted = set(re.search(r'^\./scripts/setup\.sh(.*)$', test_sh, re.MULTILINE)
                 .group(1).split('#')[0].split())
    flags = {flag for keyword, args in instructions() if keyword == 'RUN'
             and args.startswith('./scripts/setup.sh') for flag in args.split()[1:]}
    assert wanted <= flags, (wanted, flags)


def test_deps_only_needs_nothing_but_the_requirements():
    text = SETUP_SH.read_text()
    deps_part = text[:text.index('if $deps_only')]
    body = deps_part[deps_part.index('cd "$ROOT"'):]
    assert 'requirements.txt' in body
    assert 'colcon' not in body and 'src' not in body.replace('STAMP_DIR', '')


def test_cmd_not_entrypoint():
    keywords = [keyword for keyword, _ in instructions()]
    assert 'ENTRYPOINT' not in keywords
    cmd = [args for keyword, args in instructions() if keyword == 'CMD']
    assert len(cmd) == 1 and json.loads(cmd[0]) == ['./scripts/demo.sh']


def test_runs_as_a_user_that_is_not_root():
    users = [args for keyword, args in instructions() if keyword == 'USER']
    assert users, 'no USER: the image would run as root'
    assert users[-1].split(':')[0] not in ('root', '0')
    assert index_of(lambda k, a: k == 'USER') < index_of(lambda k, a: k == 'CMD')


def test_exposes_the_live_view_port():
    exposed = [args.split() for keyword, args in instructions() if keyword == 'EXPOSE']
    assert any(p.split('/')[0] == '8765' for ports in exposed for p in ports)


def test_installs_git_and_bakes_in_the_revision():
    installs = [args for keyword, args in instructions() if keyword == 'RUN'
                and 'apt-get install' in args]
    assert any(re.search(r'\bgit\b', args) for args in installs)
    steps = instructions()
    assert any(k == 'ARG' and a.split('=')[0] == 'GIT_REVISION' for k, a in steps)
    assert ('ENV', 'REPLAN_GIT_REVISION=${GIT_REVISION}') in steps
    # The recorder's run records read it where git is missing (test_run_metadata.py runs it).
    metadata = REPO_ROOT / 'src' / 'replan_ros' / 'replan_ros' / 'recording' / 'run_metadata.py'
    assert "'REPLAN_GIT_REVISION'" in metadata.read_text()


@pytest.mark.parametrize('folder', ['.venv', 'build', 'install', 'log', 'runs'])
def test_local_set_up_stays_out_of_the_context(folder):
    ignored = (REPO_ROOT / '.dockerignore').read_text().split()
    assert folder in ignored
