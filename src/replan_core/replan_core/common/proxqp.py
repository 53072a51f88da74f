"""proxsuite's ProxQP as the core uses it: a solve that depends on its input values alone.

Two things made the same QP come out differently in two runs of one scenario (the
controller's first torques 2e-9 N m apart, the runs parting from the first tick):

- **The instruction set.** ``import proxsuite`` loads the build for the widest SIMD the CPU
  has (AVX-512, else AVX2). Those builds' results depend on the heap's layout: a fresh QP
  object with the same aligned inputs gave forces up to 9e-10 N apart after other allocations
  (``test_proxqp.py``; the hypothesis, not traced into proxsuite, is that its work arrays are
  not aligned to the SIMD packet). The baseline build (SSE2: 16-byte packets, which every
  allocation meets) gave the same bits whatever the heap, as the same code on any x86-64
  machine. The core's QPs are small (12 forces; the MPC's default path
  solves its own dual): the baseline build costs 2-3 us per force solve (docs/mpc.md).
- **The inputs' addresses.** proxsuite reads vector inputs in place, and where an array starts
  decides how Eigen splits its vectorised reductions: fresh numpy arrays start where the heap
  history puts them (which wall-clock timers change). Inputs are passed at a fixed 64-byte
  alignment (``aligned``; buffers built once with ``aligned_empty``).

proxsuite picks its build in its package ``__init__`` from ``proxsuite.instructionset``; this
module answers "no AVX" there before proxsuite is first imported, so every import of proxsuite
in the process gets the baseline build (two builds cannot share a process). proxsuite is pinned
in requirements.txt; ``test_proxqp.py`` fails if an upgrade changes how the build is chosen.
"""

from __future__ import annotations

import sys
import types

import numpy as np

ALIGNMENT = 64  # bytes: one AVX-512 register, a cache line
BASELINE_BUILD = 'proxsuite.proxsuite_pywrap'


def _import_baseline():
    """The proxsuite package with its baseline build loaded (see the module docstring)."""
    if 'proxsuite' not in sys.modules:
        no_simd = types.ModuleType('proxsuite.instructionset')
        no_simd.__doc__ = 'replan_core.common.proxqp: the baseline build, whatever the CPU'
        no_simd.has_AVX2 = no_simd.has_AVX512F = lambda: False
        sys.modules['proxsuite.instructionset'] = no_simd
    import proxsuite
    build = getattr(proxsuite, '_submodule', None)
    name = getattr(build, '__name__', repr(build))
    if name != BASELINE_BUILD:
        raise ImportError(f'proxsuite loaded its {name} build, not {BASELINE_BUILD}: import '
                          'replan_core before proxsuite (runs are bit-exact only with the '
                          'baseline build; replan_core/common/proxqp.py)')
    return proxsuite


proxsuite = _import_baseline()
proxqp = proxsuite.proxqp


def aligned_empty(shape: int | tuple[int, ...]) -> np.ndarray:
    """An uninitialised C-contiguous float64 array whose data starts on an ``ALIGNMENT``
    boundary."""
    count = int(np.prod(shape))
    raw = np.empty(count * 8 + ALIGNMENT, dtype=np.uint8)
    start = (-raw.ctypes.data) % ALIGNMENT
    return raw[start:start + count * 8].view(np.float64).reshape(shape)


def is_aligned(array: np.ndarray) -> bool:
    """True for a C-contiguous float64 array whose data starts on an ``ALIGNMENT`` boundary."""
    return (array.dtype == np.float64 and array.flags.c_contiguous
            and array.ctypes.data % ALIGNMENT == 0)


def aligned(array) -> np.ndarray | None:
    """``array`` itself if ``is_aligned``, otherwise an aligned float64 copy; None stays None
    (an absent solver argument)."""
    if array is None:
        return None
    array = np.asarray(array, dtype=np.float64)
    if is_aligned(array):
        return array
    out = aligned_empty(array.shape)
    out[...] = array
    return out
