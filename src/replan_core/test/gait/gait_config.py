"""What the gait tests share: the repository's configuration folder and the legs' indices."""

from pathlib import Path

from replan_core.common.types import LEGS

CONFIG = Path(__file__).resolve().parents[4] / 'config'
LF, RF, LH, RH = (LEGS.index(n) for n in ('lf', 'rf', 'lh', 'rh'))
