"""Every script answers --help (usage, exit 0, nothing started or created) and rejects an
unknown option (usage, non-zero exit), before any set-up, node or output folder."""

from __future__ import annotations

import subprocess

import pytest
from harness import REPO_ROOT

# env.sh and preamble.sh are sourced by the others, not run.
SCRIPTS = sorted(p.name for p in (REPO_ROOT / 'scripts').glob('*.sh')
                 if p.name not in ('env.sh', 'preamble.sh'))
# Arguments that the scripts with positionals accept, so that the unknown option also comes
# after them. bench_graph.sh (not ours to change) stops parsing at its OUT_DIR, so it is only
# checked with the option first.
POSITIONALS = {
    'bench_sim.sh': ['1'],
    'cmd_vel.sh': ['0.1', '0', '0'],
    'demo.sh': ['runs/never-created'],
    'gait_report.sh': ['runs/never-created'],
    'paper_results.sh': ['runs/never-created'],
    'push.sh': ['0', '10', '0', '--duration', '0.1'],
    'replay.sh': ['no-such-bag.mcap'],
    'rerun.sh': ['no-such-bag.mcap'],
    'scenario.sh': ['config/scenarios/forward.yaml'],
    'topic.sh': ['echo', '/clock'],
}
TIMEOUT = 30.0     # generous: --help takes well under a second once set up


def repo_state() -> tuple[frozenset[str], frozenset[str]]:
    """Untracked or changed files (git) and every path under the ignored runs/ folder."""
    status = subprocess.run(['git', 'status', '--porcelain', '--untracked-files=all'],
                            cwd=REPO_ROOT, capture_output=True, text=True, timeout=30)
    lines = frozenset(status.stdout.splitlines()) if status.returncode == 0 else frozenset()
    runs = REPO_ROOT / 'runs'
    outputs = frozenset(str(p) for p in runs.rglob('*')) if runs.is_dir() else frozenset()
    return lines, outputs


def run(script: str, *args: str) -> subprocess.CompletedProcess:
    before = repo_state()
    done = subprocess.run([str(REPO_ROOT / 'scripts' / script), *args], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=TIMEOUT,
                          stdin=subprocess.DEVNULL)
    after = repo_state()
    new = (after[0] - before[0]) | (after[1] - before[1])
    assert not new, f'{script} {" ".join(args)} created or changed {sorted(new)}'
    return done


def test_every_script_is_covered():
    assert {'setup.sh', 'test.sh', 'demo.sh', 'launch.sh', 'topic.sh', 'teleop.sh'} <= set(SCRIPTS)


@pytest.mark.parametrize('script', SCRIPTS)
@pytest.mark.parametrize('flag', ['--help', '-h'])
def test_help(script, flag):
    done = run(script, flag)
    output = done.stdout + done.stderr
    assert done.returncode == 0, output
    assert 'usage' in output.lower(), output
    assert 'Traceback' not in output, output


@pytest.mark.parametrize('script', SCRIPTS)
def test_unknown_option_is_rejected(script):
    for args in ([], POSITIONALS.get(script)):
        if args is None:
            continue
        done = run(script, *args, '--no-such-option')
        output = done.stdout + done.stderr
        assert done.returncode != 0, output
        assert 'usage' in output.lower(), output
        assert 'Traceback' not in output, output
