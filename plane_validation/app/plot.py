"""Pictures (matplotlib, headless Agg backend): segmented clouds, and index curves vs t and vs k; PNG, or the
format of the file's extension (:func:`figure_format`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..formats.outputs import atomic_output

#: Formats matplotlib lists but does not write by itself: pgf is LaTeX code that needs a TeX installation.
NOT_WRITTEN = frozenset({'pgf'})


def figure_format(path: str | Path) -> str:
    """The format a figure is written in at ``path``: its extension's (PNG without one); ValueError naming the
    file unless matplotlib writes that format. Checked before the work, as :func:`.files.check_output` is."""
    from matplotlib.figure import Figure

    path = Path(path)
    formats = sorted(set(Figure().canvas.get_supported_filetypes()) - NOT_WRITTEN)
    suffix = path.suffix.lower().lstrip('.') or 'png'
    if suffix not in formats:
        raise ValueError(f'{path}: cannot write a figure as {path.suffix!r} (use '
                         f'{", ".join("." + f for f in formats)})')
    return suffix


def _save_figure(fig, path: Path, *, palette: bool = False) -> Path:
    """Save ``fig`` at ``path`` in its :func:`figure_format`, complete or not at all; ``palette``: a PNG
    with 256 colours (line plots look the same at a third of the bytes)."""
    import io

    from PIL import Image

    fmt = figure_format(path)
    with atomic_output(path) as tmp:
        if palette and fmt == 'png':
            buffer = io.BytesIO()
            fig.savefig(buffer, format='png')
            buffer.seek(0)
            with Image.open(buffer) as image:
                image.convert('RGB').quantize(colors=256).save(tmp, format='PNG', optimize=True)
        else:
            fig.savefig(tmp, format=fmt)
    return path


def plot_planes(points: np.ndarray, labels: np.ndarray, path: str | Path, *, title: str = '',
                max_points: int = 20000, seed: int = 0) -> Path:
    """3-D scatter of (n, 3) points coloured by plane label (grey = unassigned), saved to ``path`` (its
    :func:`figure_format`)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from ..core.geometry import plane_colors

    path = Path(path)
    if len(points) > max_points:
        keep = np.random.default_rng(seed).choice(len(points), max_points, replace=False)
        points, labels = points[keep], labels[keep]
    n_planes = int(labels.max()) + 1 if len(labels) else 0
    palette = np.vstack([plane_colors(n_planes) / 255.0, [[0.6, 0.6, 0.6]]])
    colors = palette[np.where(labels >= 0, labels, n_planes)]
    fig = plt.figure(figsize=(7, 6), dpi=100)
    ax = fig.add_subplot(projection='3d')
    ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colors, s=1.5, linewidths=0)
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.set_title(f'{title}\n{n_planes} planes (grey: unassigned)')
    fig.tight_layout()
    try:
        return _save_figure(fig, path)
    finally:
        plt.close(fig)


def plot_cloud_message(msg, path: str | Path, *, title: str = '') -> Path:
    """Plot a ``segmented`` PointCloud2 (x, y, z, plane_id) as published by the node."""
    from ..formats.pointcloud2 import structured_array, xyz_array
    return plot_planes(xyz_array(msg), np.asarray(structured_array(msg)['plane_id']), path, title=title)


# -- index curves (the paper's figures) ------------------------------------------------------------

#: Resolution of the index figures: 800 x 576 px for the sweep, 50-100 KB.
DPI = 80
#: Curves with more points than this are drawn without markers.
MAX_MARKERS = 40
#: Line style per index, the same in every figure.
_STYLE = {'gs_planes': dict(color='tab:red', marker='o', label='GSplanes'),
          'gs': dict(color='tab:blue', marker='s', label='GS'),
          'silhouette': dict(color='tab:green', marker='^', label='silhouette (mean $s_i$)'),
          'dunn': dict(color='tab:purple', marker='D', label='Dunn'),
          'davies_bouldin': dict(color='tab:orange', marker='v', label='Davies–Bouldin (eq. 3)'),
          'davies_bouldin_classic': dict(color='tab:brown', marker='x', label='Davies–Bouldin (centroids)'),
          'plane_silhouette': dict(color='black', marker='*', label='PS (point-to-plane)')}


def _figure(rows: int, cols: int, size: tuple[float, float]):
    """A matplotlib Figure drawn by the Agg canvas (no pyplot, no global backend state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=DPI, layout='constrained')
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, squeeze=False)


def _finite(values) -> np.ndarray:
    """Floats with inf replaced by NaN (matplotlib leaves a gap)."""
    arr = np.asarray(values, dtype=float)
    return np.where(np.isfinite(arr), arr, np.nan)


def _plot_index(ax, x, values, name: str, *, best: int | None = None, unit_of_best: str = '') -> None:
    """One index curve; markers only on short curves (dense sweeps read better as lines)."""
    style = dict(_STYLE[name])
    if best is not None:
        style['label'] += f' (best at {unit_of_best.format(best)})'
    if len(x) > MAX_MARKERS:
        style.pop('marker')
    ax.plot(x, _finite(values), markersize=3.5, linewidth=1.4, **style)


def _is_geometric(t: np.ndarray) -> bool:
    if len(t) < 3 or np.any(t <= 0):
        return False
    ratios = t[1:] / t[:-1]
    return bool(np.allclose(ratios, ratios[0], rtol=1e-6) and ratios[0] > 1.05)


def plot_sweep(result, path: str | Path, *, title: str = '', unit: str = 'm',
               true_planes: int | None = None) -> Path:
    """The paper's Fig. 1/3/4/5/7 (indices vs t) and Fig. 6/8 (planes vs t) as one figure (:func:`figure_format`).

    result: a :class:`~plane_validation.core.tuning_result.TuningResult`; four panels over the candidate
    tolerances t (in ``unit``): silhouette indices, Dunn, Davies-Bouldin, number of planes; the
    chosen t is a dashed vertical line in each. ``true_planes`` draws the known count.
    """
    path = Path(path)
    t = np.array([r.tolerance for r in result.rows])
    chosen = result.tolerance
    fig, axes = _figure(2, 2, (10.0, 7.2))
    (ax_sil, ax_dunn), (ax_db, ax_count) = axes
    values = {name: [getattr(r.indices, name) for r in result.rows] for name in _STYLE}
    for name in ('plane_silhouette', 'gs_planes', 'gs', 'silhouette'):
        _plot_index(ax_sil, t, values[name], name)
    se = np.array([r.indices.gs_planes_se for r in result.rows])
    if np.any(se > 0):
        gsp = _finite(values['gs_planes'])
        ax_sil.fill_between(t, gsp - 2 * se, gsp + 2 * se, color='tab:red', alpha=0.15, linewidth=0,
                            label='GSplanes ± 2 SE (sampled)')
    ax_sil.set_ylabel('silhouette index (higher is better)')
    ax_sil.set_title('Silhouettes: PS, GS, GSplanes')
    _plot_index(ax_dunn, t, values['dunn'], 'dunn')
    ax_dunn.set_ylabel('Dunn index (higher is better)')
    ax_dunn.set_title('Dunn index (eq. 2)')
    for name in ('davies_bouldin', 'davies_bouldin_classic'):
        _plot_index(ax_db, t, values[name], name)
    db = _finite(values['davies_bouldin'] + values['davies_bouldin_classic'])
    if np.nanmax(db, initial=0) > 20 * max(np.nanmin(db[db > 0], initial=1), 1e-12):
        ax_db.set_yscale('log')
    ax_db.set_ylabel('Davies–Bouldin index (lower is better)')
    ax_db.set_title('Davies–Bouldin index (eq. 3)')
    counts = [r.n_planes for r in result.rows]
    ax_count.plot(t, counts, color='black', marker='o' if len(t) <= MAX_MARKERS else None, markersize=3.5,
                  linewidth=1.4, drawstyle='steps-mid', label='planes found')
    if true_planes is not None:
        ax_count.axhline(true_planes, color='tab:gray', linestyle=':', linewidth=1.5,
                         label=f'true number of planes ({true_planes})')
    ax_count.set_ylabel('number of planes')
    ax_count.set_title('Planes found by sequential RANSAC')
    ax_count.yaxis.get_major_locator().set_params(integer=True)
    geometric = _is_geometric(t)
    for ax in axes.flat:
        ax.axvline(chosen, color='crimson', linestyle='--', linewidth=1.3,
                   label=f'chosen t = {chosen:.3g} {unit} ({result.criterion})')
        if geometric:
            ax.set_xscale('log')
        ax.set_xlabel(f'RANSAC tolerance t [{unit}]')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7.5, loc='best')
    verdict = 'reliable' if result.reliable else 'NOT reliable'
    fig.suptitle(f'{title + ": " if title else ""}validity indices vs tolerance; chosen t = {chosen:.3g} {unit}, '
                 f'{result.segmentation.n_planes} planes, {verdict}', fontsize=11)
    return _save_figure(fig, path, palette=True)


def plot_plane_count(result, path: str | Path, *, title: str = '', true_planes: int | None = None) -> Path:
    """The paper's Fig. 2: indices of the first k planes vs k, the selected k marked.

    result: a :class:`~plane_validation.core.plane_count.PlaneCountResult`. Left: GS, GSplanes, silhouette
    and the smallest per-plane silhouette S_j (the selection rule keeps the largest k with all
    S_j >= MIN_PLANE_SILHOUETTE); right: Dunn and Davies-Bouldin. Legend entries give each
    index's own best k.
    """
    from ..core.criteria import CRITERIA
    from ..core.plane_count import MIN_PLANE_SILHOUETTE

    path = Path(path)
    k = np.array(result.counts)
    fig, axes = _figure(1, 2, (10.0, 4.4))
    ax_sil, ax_other = axes[0]
    if len(k) == 0:
        for ax in axes.flat:
            ax.text(0.5, 0.5, 'no planes found', ha='center', va='center', transform=ax.transAxes)
    values = {name: [getattr(x, name) for x in result.indices] for name in CRITERIA}
    best = {name: result.best_by(name) for name in CRITERIA} if len(k) else {}
    for name in ('plane_silhouette', 'gs_planes', 'gs', 'silhouette'):
        _plot_index(ax_sil, k, values[name], name, best=best.get(name), unit_of_best='k = {}')
    lowest = [min(x.plane_silhouettes, default=np.nan) for x in result.indices]
    ax_sil.plot(k, _finite(lowest), color='tab:red', linestyle=':', marker='.', label='smallest plane $S_j$')
    ax_sil.axhline(MIN_PLANE_SILHOUETTE, color='tab:gray', linewidth=1, linestyle='-.',
                   label=f'$S_j$ threshold {MIN_PLANE_SILHOUETTE}')
    ax_sil.set_ylabel('silhouette index (higher is better)')
    ax_sil.set_title('Global silhouettes of the first k planes')
    _plot_index(ax_other, k, values['dunn'], 'dunn', best=best.get('dunn'), unit_of_best='k = {}')
    ax_other.set_ylabel('Dunn index (higher is better)')
    ax_db = ax_other.twinx()
    _plot_index(ax_db, k, values['davies_bouldin'], 'davies_bouldin', best=best.get('davies_bouldin'),
                unit_of_best='k = {}')
    ax_db.set_ylabel('Davies–Bouldin index (lower is better)')
    ax_other.set_title('Dunn and Davies–Bouldin of the first k planes')
    for ax in (ax_sil, ax_other):
        if len(k):
            ax.axvline(result.n_planes, color='crimson', linestyle='--', linewidth=1.3,
                       label=f'selected k = {result.n_planes} ({result.criterion} rule)')
        if true_planes is not None:
            ax.axvline(true_planes, color='tab:gray', linestyle=':', linewidth=1.5,
                       label=f'true number of planes ({true_planes})')
        ax.set_xlabel('number of planes k (first k extracted; the rest unassigned)')
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.grid(True, alpha=0.3)
    ax_sil.legend(fontsize=7.5, loc='best')
    handles = ax_other.get_legend_handles_labels()
    twin = ax_db.get_legend_handles_labels()
    ax_other.legend(handles[0] + twin[0], handles[1] + twin[1], fontsize=7.5, loc='best')
    fig.suptitle(f'{title + ": " if title else ""}indices vs number of planes at t = '
                 f'{result.segmentation.tolerance:.3g}; selected k = {result.n_planes}', fontsize=11)
    return _save_figure(fig, path, palette=True)


# -- batch reports ---------------------------------------------------------------------------------

#: Marker colour of a frame's status in the batch reports.
_LEVEL_COLOR = {'OK': 'tab:green', 'WARN': 'tab:orange', 'ERROR': 'tab:red'}


def plot_bag_report(summary: dict, path: str | Path) -> Path:
    """One bag of a batch over bag time (s from its first frame): the silhouette indices with PS, Dunn and
    Davies-Bouldin, the tolerance t and the number of planes; each frame's status marked (green OK, orange WARN:
    not reliable, red ERROR). ``summary``: an :func:`~.fleet.summary_document`."""
    frames = summary['frames']
    start = frames[0]['timestamp'] if frames else 0
    x = np.array([(f['timestamp'] - start) * 1e-9 for f in frames])
    series = {key: _finite([np.nan if f[key] is None else f[key] for f in frames])
              for key in ('plane_silhouette', 'gs_planes', 'gs', 'silhouette', 'dunn', 'davies_bouldin',
                          'tolerance', 'planes')}
    fig, axes = _figure(2, 2, (10.0, 6.4))
    (ax_sil, ax_sep), (ax_t, ax_k) = axes
    for name in ('plane_silhouette', 'gs_planes', 'gs', 'silhouette'):
        _plot_index(ax_sil, x, series[name], name)
    ax_sil.set_ylabel('silhouette index (higher is better)')
    ax_sil.set_title('PS and the silhouettes')
    _plot_index(ax_sep, x, series['dunn'], 'dunn')
    ax_sep.set_ylabel('Dunn index (higher is better)')
    ax_db = ax_sep.twinx()
    _plot_index(ax_db, x, series['davies_bouldin'], 'davies_bouldin')
    ax_db.set_ylabel('Davies–Bouldin index (lower is better)')
    ax_sep.set_title('Dunn and Davies–Bouldin')
    ax_t.plot(x, series['tolerance'], color='crimson', drawstyle='steps-post', marker='.', label='t in use')
    ax_t.set_ylabel('RANSAC tolerance t [m]')
    ax_t.set_title('Tolerance t in use (a quick estimate until the first sweep ends)')
    ax_k.plot(x, series['planes'], color='black', drawstyle='steps-post', marker='.', label='planes found')
    ax_k.set_ylabel('number of planes')
    ax_k.set_title('Planes per frame')
    ax_k.yaxis.get_major_locator().set_params(integer=True)
    ax_k.set_ylim(bottom=0, top=max(np.nanmax(series['planes'], initial=0), 1) + 0.5)
    levels = [f['level'] for f in frames]
    for ax in axes.flat:
        low = ax.get_ylim()[0] if len(x) else 0
        for level, color in _LEVEL_COLOR.items():
            at = [i for i, name in enumerate(levels) if name == level]
            if at:
                ax.scatter(x[at], np.full(len(at), low), marker='|', s=120, color=color, clip_on=False,
                           label=f'{level} ({len(at)} frames)', zorder=3)
        ax.set_xlabel('bag time [s] from the first frame')
        ax.grid(True, alpha=0.3)
    for ax in (ax_sil, ax_t, ax_k):
        ax.legend(fontsize=7.5, loc='best')
    handles = [sum(pair, []) for pair in zip(ax_sep.get_legend_handles_labels(), ax_db.get_legend_handles_labels())]
    ax_sep.legend(*handles, fontsize=7.5, loc='best')
    fig.suptitle(f'{summary["bag"]} [{summary["topic"]}]: {summary["frame_count"]} frames, '
                 f'{summary["reliable_share"]:.0%} reliable', fontsize=11)
    return _save_figure(fig, path, palette=True)


def plot_fleet(rows, path: str | Path) -> Path:
    """The batch at a glance: per bag, the share of reliable frames and the tuned t (median, min-max bar);
    failed bags are named in red with no bar. ``rows``: :class:`~.fleet.Row` objects."""
    names = [r.name for r in rows]
    y = np.arange(len(rows))
    fig, axes = _figure(1, 2, (10.0, 1.2 + 0.32 * max(len(rows), 3)))
    ax_share, ax_t = axes[0]
    share = _finite([r.reliable_share for r in rows])
    ax_share.barh(y, share, color=[_LEVEL_COLOR['OK' if s >= 0.5 else 'WARN'] for s in np.nan_to_num(share)])
    for at, value in zip(y, share):
        ax_share.text(0.01, at, 'failed' if np.isnan(value) else f'{value:.0%}', va='center', fontsize=8)
    ax_share.set_xlim(0, 1)
    ax_share.set_xlabel('share of frames with reliable planes (status OK)')
    med = _finite([r.tolerance_median for r in rows])
    spread = np.array([[m - r.tolerance_min, r.tolerance_max - m] for m, r in zip(med, rows)]).T.reshape(2, -1)
    ax_t.errorbar(med, y, xerr=np.nan_to_num(spread), fmt='o', color='crimson', capsize=3)
    ax_t.set_xlabel('tolerance t in use [m]: median, min-max over frames')
    if np.isfinite(med).any() and np.nanmin(med) > 0 and np.nanmax(med) > 10 * np.nanmin(med):
        ax_t.set_xscale('log')
    for ax in (ax_share, ax_t):
        ax.set_yticks(y, names, fontsize=8)
        ax.set_ylim(len(rows) - 0.5, -0.5)
        ax.grid(True, axis='x', alpha=0.3)
        for tick, r in zip(ax.get_yticklabels(), rows):
            if r.status.value == 'failed':
                tick.set_color('tab:red')
    failed = sum(r.status.value == 'failed' for r in rows)
    fig.suptitle(f'{len(rows)} bags' + (f', {failed} failed (red)' if failed else ''), fontsize=11)
    return _save_figure(fig, path, palette=True)
