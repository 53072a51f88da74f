"""The results page's plots (``page.py`` draws them through ``Page.plot``): one function per
figure, each from the rows of its experiment, returning the matplotlib figure."""

from __future__ import annotations

import numpy as np

from replan_experiments.stats import values


def plot_push(plt, table: dict):
    """Largest impulse survived per push phase and setting: mean over the seeds, bars from the
    least to the most."""
    fig, ax = plt.subplots(figsize=(8, 3.6))
    width = 0.8 / max(len(table), 1)
    for i, (name, entries) in enumerate(table.items()):
        phases = sorted({p['phase'] for p in entries})
        survived = [[p['survived_ns'] for p in entries if p['phase'] == k] for k in phases]
        mean = np.array([np.mean(v) for v in survived])
        low = mean - np.array([min(v) for v in survived])
        high = np.array([max(v) for v in survived]) - mean
        ax.bar(np.arange(len(phases)) + i * width, mean, width, yerr=[low, high], capsize=2,
               label=name.replace('_', ' '))
    ax.axhline(30.0, color='tab:red', lw=0.8, label='target 30 N s')
    ax.set_xlabel('push phase (mean over the seeds, bars from the least to the most)')
    ax.set_ylabel('largest impulse survived [N s]')
    ax.legend(fontsize=7)
    return fig


def plot_windows(plt, rows, windows):
    """Steady velocity error and CoP margin per replan window, box plots over the runs."""
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2))
    for ax, key, label, scale in ((axes[0], 'steady_error_mps', 'steady velocity error [m/s]',
                                   1.0),
                                  (axes[1], 'cop_margin_p5_m', 'CoP margin p5 [cm]', 100.0)):
        data = [np.asarray(values([r for r in rows if r['window'] == w], key)) * scale
                for w in windows]
        ax.boxplot(data)
        ax.set_xticks(range(1, len(windows) + 1), [str(w) for w in windows])
        ax.set_xlabel('replan window [touchdowns]')
        ax.set_ylabel(label)
    return fig


def plot_haptic(plt, rows):
    """Touchdown pitch peaks per terrain, haptic on and off: mean and spread over the runs."""
    terrains = list(dict.fromkeys(r['terrain'] for r in rows))
    fig, ax = plt.subplots(figsize=(8, 3.4))
    for k, mode in enumerate((True, False)):
        data = [values([r for r in rows if r['terrain'] == t and r['haptic'] == mode],
                       'pitch_peak_mean_deg') for t in terrains]
        x = np.arange(len(terrains)) + (k - 0.5) * 0.3
        means = [np.mean(d) if d else np.nan for d in data]
        errs = [np.std(d, ddof=1) if len(d) > 1 else 0.0 for d in data]
        ax.bar(x, means, 0.3, yerr=errs, label='haptic on' if mode else 'haptic off')
    ax.set_xticks(np.arange(len(terrains)), [t.replace('_', ' ') for t in terrains])
    ax.set_ylabel('touchdown pitch peak [deg]')
    ax.legend(fontsize=7)
    return fig
