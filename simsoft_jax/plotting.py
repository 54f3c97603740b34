"""Figures and animations of rods (matplotlib only; the core never imports this module).

Every function takes plain NumPy arrays in SI units and returns a
:class:`matplotlib.figure.Figure` (or the path of a written animation); nothing here calls
``plt.show``, so it works under the non-interactive ``Agg`` backend. Shapes:

* positions ``(N, 3)`` (one configuration of N nodes, m) or ``(T, N, 3)`` (T configurations:
  load steps or time snapshots);
* rotations ``(N, 3, 3)`` or ``(T, N, 3, 3)``: section frames whose columns are the local
  axes in world coordinates (column 0 = centreline tangent, 1 and 2 = the section's
  principal axes y and z, scene-format conventions).

The cross-section orientation is drawn as a *ribbon*: a strip of width ``w`` centred on the
centreline and spanned by the local axis ``axis`` of each frame (edges ``p -/+ (w/2) R[:, axis]``),
so bending about that axis keeps the ribbon flat and twist shows as the strip winding; small
frame triads (x red, y green, z blue) are optional. ``*_result`` helpers take a
:class:`simsoft_jax.Result` and a rod name and draw the helical interpolation between nodes
(the paper's eq. 27, :func:`simsoft_jax.analysis.kinematics.sample_shape`).

Also: tip trajectories (components vs time, the paper's Figs. 6-8 and 11), error bars grouped by
load angle (the style of the paper's Figs. 16-18) and work-precision plots (error vs wall
time, log-log).
"""
from __future__ import annotations

import functools

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib import animation, colormaps
from matplotlib.ticker import MaxNLocator, NullFormatter, ScalarFormatter
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

TRIAD_COLORS = ("tab:red", "tab:green", "tab:blue")


# ---------------------------------------------------------------------------- validation

def _array(name, value, shapes):
    """``value`` as a float array whose shape matches one of ``shapes`` (tuples with None
    for free sizes); otherwise a ValueError naming ``name``."""
    a = np.asarray(value, dtype=float)
    for shape in shapes:
        if a.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, a.shape)):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{name}: contains non-finite values")
            return a
    wanted = " or ".join("(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"
                         for shape in shapes)
    raise ValueError(f"{name}: expected shape {wanted}, got {a.shape}")


def _frames(positions, rotations, stacked):
    """Validated ``(T, N, 3)`` positions and ``(T, N, 3, 3)`` rotations (or None).

    ``stacked`` True: inputs must carry the T axis; False: a single configuration (N, 3),
    returned with T = 1."""
    if stacked:
        p = _array("positions", positions, [(None, None, 3)])
    else:
        p = _array("positions", positions, [(None, 3)])[None]
    if p.shape[1] < 2:
        raise ValueError(f"positions: a rod needs at least 2 nodes, got {p.shape[1]}")
    if rotations is None:
        return p, None
    R = _array("rotations", rotations,
               [(p.shape[0], p.shape[1], 3, 3)] if stacked else [(p.shape[1], 3, 3)])
    return p, R.reshape(p.shape[0], p.shape[1], 3, 3)


# ------------------------------------------------------------------------------ 3-D axes

def _axes3d(ax, figsize=(7.0, 5.5)):
    if ax is None:
        fig = plt.figure(figsize=figsize)
        ax = fig.add_subplot(projection="3d")
    return ax.figure, ax


def set_equal_aspect(ax, points):
    """Equal scaling of a 3-D axes around ``points`` (..., 3) (m): a cube of the largest
    extent, centred on the data, with a cubic box."""
    pts = np.asarray(points, float).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    half = 0.5 * max(float(np.max(hi - lo)), 1e-12) * 1.05
    centre = 0.5 * (lo + hi)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")


def _default_width(points):
    """Ribbon width: 6 % of the largest extent of ``points`` (m)."""
    pts = np.asarray(points, float).reshape(-1, 3)
    return 0.06 * max(float(np.max(np.ptp(pts, axis=0))), 1e-12)


def ribbon_vertices(positions, rotations, width, axis=1):
    """Quadrilaterals of the section ribbon, ``(N - 1, 4, 3)`` (m).

    positions (N, 3), rotations (N, 3, 3); node i contributes the edge points
    ``p_i - (width/2) R_i[:, axis]`` and ``p_i + (width/2) R_i[:, axis]``; quad e is
    ``[minus_e, plus_e, plus_e+1, minus_e+1]``. ``axis`` 1 (local y) or 2 (local z).
    """
    p, R = _frames(positions, rotations, stacked=False)
    if axis not in (1, 2):
        raise ValueError(f"axis: must be 1 (local y) or 2 (local z), got {axis!r}")
    if not width > 0:
        raise ValueError(f"width: must be > 0, got {width!r}")
    offset = 0.5 * width * R[0, :, :, axis]
    minus, plus = p[0] - offset, p[0] + offset
    return np.stack([minus[:-1], plus[:-1], plus[1:], minus[1:]], axis=1)


def _ribbon_edges(quads):
    """The two edge lines ``(N, 3)`` of a ribbon's quadrilaterals ``(N - 1, 4, 3)``."""
    return [np.concatenate([quads[:, k], quads[-1:, 3 - k]]) for k in (0, 1)]


def _draw_rod(ax, p, R, color, width, axis, triads, label):
    """One configuration: centreline, ribbon (with its two edge lines, gids
    ``ribbon_minus`` / ``ribbon_plus``) and optional triads."""
    ax.plot(*p.T, color=color, lw=2.0, label=label)
    if R is None:
        return
    quads = ribbon_vertices(p, R, width, axis)
    ax.add_collection3d(Poly3DCollection(quads, facecolor=color, alpha=0.35,
                                         edgecolor="none"))
    for edge, gid in zip(_ribbon_edges(quads), ("ribbon_minus", "ribbon_plus")):
        ax.plot(*edge.T, color=color, lw=0.6, gid=gid)
    if triads:
        step = max(1, len(p) // 12)
        for Ri, pi in zip(R[::step], p[::step]):
            for k in range(3):
                ax.plot(*np.stack([pi, pi + 1.5 * width * Ri[:, k]]).T,
                        color=TRIAD_COLORS[k], lw=0.8)


# ----------------------------------------------------------------------------- rods in 3-D

def plot_rod(positions, rotations=None, *, ax=None, width=None, axis=1, triads=False,
             color="tab:blue", label=None, title=None):
    """One rod configuration in 3-D with equal axis scaling (the paper's Figs. 5, 9, 20, 22).

    positions (N, 3) m; rotations (N, 3, 3) or None (centreline only). ``width`` (m) of the
    ribbon spanned by local axis ``axis`` (default 6 % of the rod's extent); ``triads``
    also draws the local x, y, z axes (red, green, blue). Returns the Figure.
    """
    p, R = _frames(positions, rotations, stacked=False)
    fig, ax = _axes3d(ax)
    width = _default_width(p) if width is None else width
    _draw_rod(ax, p[0], None if R is None else R[0], color, width, axis, triads, label)
    set_equal_aspect(ax, p)
    if title:
        ax.set_title(title)
    if label:
        ax.legend()
    return fig


def plot_configurations(positions, rotations=None, *, labels=None, cmap="viridis",
                        ax=None, width=None, axis=1, title=None, colorbar_label=None,
                        values=None, references=None):
    """Several configurations overlaid, coloured along a colormap (load steps or time
    snapshots; the paper's Figs. 9, 20, 22).

    positions (K, N, 3) m; rotations (K, N, 3, 3) or None. ``labels`` (K strings) make a
    legend; ``values`` (K,) (e.g. times in s or loads) make a colorbar titled
    ``colorbar_label`` instead. ``references`` (K, M, 3): curves drawn dashed black over
    each configuration (e.g. exact solutions). Returns the Figure.
    """
    p, R = _frames(positions, rotations, stacked=True)
    k = p.shape[0]
    if labels is not None and len(labels) != k:
        raise ValueError(f"labels: expected {k} labels, got {len(labels)}")
    if values is not None:
        values = _array("values", values, [(k,)])
    if references is not None:
        references = _array("references", references, [(k, None, 3)])
    fig, ax = _axes3d(ax)
    width = _default_width(p) if width is None else width
    colormap = colormaps[cmap]
    if values is not None and np.ptp(values) > 0:
        shades = (values - values.min()) / np.ptp(values)
    else:
        shades = np.linspace(0.0, 1.0, k) if k > 1 else np.zeros(1)
    for i in range(k):
        _draw_rod(ax, p[i], None if R is None else R[i], colormap(shades[i]), width, axis,
                  False, None if labels is None else labels[i])
        if references is not None:
            ax.plot(*references[i].T, "k--", lw=0.9,
                    label="exact" if (i == k - 1 and labels is not None) else None)
    set_equal_aspect(ax, p if references is None else np.concatenate(
        [p.reshape(-1, 3), references.reshape(-1, 3)]))
    if labels is not None:
        ax.legend(fontsize="small", loc="upper left")
    elif values is not None:
        mappable = plt.cm.ScalarMappable(
            cmap=colormap, norm=plt.Normalize(values.min(), values.max()))
        fig.colorbar(mappable, ax=ax, shrink=0.6, label=colorbar_label)
    if title:
        ax.set_title(title)
    return fig


def plot_tip_trajectory(time, tip, *, reference=None, components=("x", "y", "z"),
                        ax=None, title=None, ylabel="tip position [m]"):
    """Tip position components vs time (the paper's Figs. 6-8, 11).

    time (T,) s; tip (T, 3) m; ``reference`` (T, 3) drawn as solid lines with the simulation
    dotted (the paper's Fig. 11 style). Returns the Figure.
    """
    t = _array("time", time, [(None,)])
    tip = _array("tip", tip, [(len(t), 3)])
    if reference is not None:
        reference = _array("reference", reference, [(len(t), 3)])
    if ax is None:
        fig, ax = plt.subplots(figsize=(7.0, 4.0))
    fig = ax.figure
    for k, name in enumerate(components):
        color = TRIAD_COLORS[k]
        if reference is not None:
            ax.plot(t, reference[:, k], color=color, lw=1.5, label=f"{name} exact")
            ax.plot(t, tip[:, k], ":", color="k", lw=1.5,
                    label="simulation" if k == 0 else None)
        else:
            ax.plot(t, tip[:, k], color=color, lw=1.5, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    if title:
        ax.set_title(title)
    return fig


def animate_rod(positions, path, rotations=None, *, time=None, fps=20, width=None, axis=1,
                title=None, max_frames=120):
    """Write an animation of a rod's motion and return its path.

    positions (T, N, 3) m, rotations (T, N, 3, 3) or None, time (T,) s (shown in the
    title). ``path`` ending in ``.gif`` is encoded by Pillow;
    ``.mp4`` uses ffmpeg and raises a RuntimeError when ffmpeg is not installed. At most
    ``max_frames`` evenly spaced frames are drawn, each once: the axes, fixed (equal
    scaling) over the whole motion, are rendered a single time and every frame draws only
    the rod, its tip and the title over them.
    """
    p, R = _frames(positions, rotations, stacked=True)
    if time is not None:
        time = _array("time", time, [(p.shape[0],)])
    path = Path(path)
    if path.suffix not in (".gif", ".mp4"):
        raise ValueError(f"path: unsupported suffix {path.suffix!r} (use .gif or .mp4)")
    if path.suffix == ".mp4" and not animation.FFMpegWriter.isAvailable():
        raise RuntimeError(f"path: {path.name} needs ffmpeg, which is not installed "
                           "(write a .gif instead)")
    frames = np.unique(np.linspace(0, p.shape[0] - 1, min(max_frames, p.shape[0])).round()
                       .astype(int))
    width = _default_width(p) if width is None else width
    fig, ax = _axes3d(None, figsize=(5.5, 5.0))
    set_equal_aspect(ax, p)
    head = f"{title}  " if title else ""
    rod = _MovingRod(ax, R is not None)

    def draw(i):
        rod.update(p[i], None if R is None else R[i], width, axis)
        ax.set_title(head + (f"t = {time[i]:.2f} s" if time is not None else f"frame {i}"))

    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        if path.suffix == ".gif":
            _write_gif(fig, rod.artists + [ax.title], draw, frames, path, fps)
        else:
            writer = animation.FFMpegWriter(fps=fps)
            with writer.saving(fig, str(path), dpi=fig.dpi):
                for i in frames:
                    draw(i)
                    writer.grab_frame()
    finally:
        plt.close(fig)
    return path


class _MovingRod:
    """The artists of one rod in an animation (centreline, ribbon and its edges, tip),
    created once and moved by :meth:`update`."""

    def __init__(self, ax, ribbon: bool):
        self.line = ax.plot([], [], [], color="tab:blue", lw=2.0)[0]
        self.tip = ax.plot([], [], [], "o", color="tab:red", ms=4)[0]
        self.artists = [self.line, self.tip]
        self.ribbon = None
        if ribbon:
            self.ribbon = Poly3DCollection(np.zeros((1, 4, 3)), facecolor="tab:blue",
                                           alpha=0.35, edgecolor="none")
            ax.add_collection3d(self.ribbon, autolim=False)
            self.edges = [ax.plot([], [], [], color="tab:blue", lw=0.6)[0] for _ in (0, 1)]
            self.artists += [self.ribbon, *self.edges]

    def update(self, p, R, width, axis):
        """Move to positions ``p`` (N, 3) m and rotations ``R`` (N, 3, 3) (or None)."""
        self.line.set_data_3d(*p.T)
        self.tip.set_data_3d(*p[-1:].T)
        if self.ribbon is not None:
            quads = ribbon_vertices(p, R, width, axis)
            self.ribbon.set_verts(quads)
            for line, edge in zip(self.edges, _ribbon_edges(quads)):
                line.set_data_3d(*edge.T)


def _write_gif(fig, artists, draw, frames, path, fps):
    """Render the figure without ``artists`` once, then per frame ``draw(i)`` and paint
    only ``artists`` over that background; encode the frames with Pillow (a palette per
    frame, fast octree) at ``fps`` frames per second."""
    from PIL import Image
    canvas = fig.canvas
    for artist in artists:
        artist.set_animated(True)       # left out of the full draw below
    draw(frames[0])
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for i in frames:
        draw(i)
        canvas.restore_region(background)
        for artist in artists:
            if hasattr(artist, "do_3d_projection"):
                artist.do_3d_projection()
            fig.draw_artist(artist)
        images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3].copy())
                      .quantize(method=Image.Quantize.FASTOCTREE))
    images[0].save(path, save_all=True, append_images=images[1:],
                   duration=round(1000.0 / fps), loop=0)


# ------------------------------------------------------------------------- error figures

def _ragged(name, value, groups):
    rows = [np.atleast_1d(np.asarray(row, float)) for row in value]
    if len(rows) != groups or any(r.ndim != 1 for r in rows):
        raise ValueError(f"{name}: expected {groups} one-dimensional rows (one per group), "
                         f"got {len(rows)}")
    return rows


def plot_error_bars(groups, mean, std, *, case_labels=None, ax=None, title=None,
                    xlabel="loading angle [deg]", ylabel="error [%]"):
    """Grouped bars of a mean error per load case with its standard deviation as error bar,
    one group per loading angle (the style of the paper's Figs. 16-18, Princeton beam).

    groups (G,) labels (e.g. angles in degrees); mean, std: G rows, row g holding one value
    per load case of group g (rows may differ in length, e.g. 4 loads at 30 deg and 3 at
    45 deg). ``case_labels``: one legend label per bar position (e.g. "f0", "2 f0").
    Returns the Figure.
    """
    groups = list(groups)
    mean = _ragged("mean", mean, len(groups))
    std = _ragged("std", std, len(groups))
    for g, (m, s) in enumerate(zip(mean, std)):
        if m.shape != s.shape:
            raise ValueError(f"std: row {g} has {s.size} values, mean has {m.size}")
    cases = max(m.size for m in mean)
    if case_labels is not None and len(case_labels) < cases:
        raise ValueError(f"case_labels: expected {cases} labels, got {len(case_labels)}")
    if ax is None:
        fig, ax = plt.subplots(figsize=(8.0, 4.0))
    fig = ax.figure
    bar = 0.8 / cases
    colors = colormaps["viridis"](np.linspace(0.1, 0.9, cases))
    for c in range(cases):
        xs = [g + (c - (cases - 1) / 2) * bar for g, m in enumerate(mean) if c < m.size]
        ys = [m[c] for m in mean if c < m.size]
        es = [s[c] for s in std if c < s.size]
        ax.bar(xs, ys, bar * 0.9, yerr=es, capsize=2, color=colors[c],
               label=None if case_labels is None else case_labels[c])
    ax.set_xticks(range(len(groups)), [str(g) for g in groups])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(axis="y", alpha=0.3)
    if case_labels is not None:
        ax.legend(fontsize="small", ncol=min(cases, 4))
    if title:
        ax.set_title(title)
    return fig


def plot_work_precision(series, *, ax=None, title=None, xlabel="wall time [s]",
                        ylabel="error"):
    """Work-precision diagram: error vs wall time, log-log, one marked line per series.

    series: mapping name -> (wall_times (K,) s, errors (K,)), all values > 0.
    Returns the Figure.
    """
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.0, 4.5))
    fig = ax.figure
    spans = []
    for name, (times, errors) in series.items():
        t = _array(f"series[{name!r}] wall times", times, [(None,)])
        e = _array(f"series[{name!r}] errors", errors, [(len(t),)])
        if np.any(t <= 0) or np.any(e <= 0):
            raise ValueError(f"series[{name!r}]: wall times and errors must be > 0 (log axes)")
        ax.loglog(t, e, "o-", label=str(name))
        spans.append((t, e))
    for k, axis in enumerate((ax.xaxis, ax.yaxis)):
        values = np.concatenate([span[k] for span in spans])
        if values.max() < 10.0 * values.min():   # under a decade: four plain ticks, not a
            axis.set_major_locator(MaxNLocator(4))   # crowd of labelled minor ones
            axis.set_major_formatter(ScalarFormatter())
            axis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(which="both", alpha=0.3)
    ax.legend(fontsize="small")
    if title:
        ax.set_title(title)
    return fig


# -------------------------------------------------------------------- Result conveniences

@functools.lru_cache(maxsize=8)
def _samplers(samples_per_element: int):
    """Jitted single and time-batched shape samplers (a few kept, not one per call)."""
    import jax

    from .analysis.kinematics import sample_shape

    one = lambda Ri, pi: sample_shape(Ri, pi, samples_per_element)  # noqa: E731
    return jax.jit(one), jax.jit(jax.vmap(one))


def sample_result(result, rod, samples_per_element=6):
    """Helical interpolation (the paper's eq. 27) of ``rod`` in a :class:`simsoft_jax.Result`:
    ``(positions, rotations)`` of shapes (M, 3), (M, 3, 3) for a static result or
    (T, M, 3), (T, M, 3, 3) for a dynamic one, ``M = elements * samples_per_element + 1``."""
    R, p = result.rotations(rod), result.positions(rod)
    single, batched = _samplers(int(samples_per_element))
    Rs, ps = (single if p.ndim == 2 else batched)(R, p)
    return np.asarray(ps), np.asarray(Rs)


def plot_result(result, rod, *, time_index=-1, samples_per_element=6, **kwargs):
    """:func:`plot_rod` of ``rod`` in a Result (static, or the saved state ``time_index``
    of a dynamic one), with the helical interpolation between nodes."""
    p, R = sample_result(result, rod, samples_per_element)
    if p.ndim == 3:
        p, R = p[time_index], R[time_index]
    kwargs.setdefault("title", f"{result.name or rod}")
    return plot_rod(p, R, **kwargs)


def plot_result_snapshots(result, rod, count=6, *, samples_per_element=6, **kwargs):
    """:func:`plot_configurations` of ``count`` evenly spaced saved states of a dynamic
    Result, coloured by time (colorbar in s)."""
    p, R = sample_result(result, rod, samples_per_element)
    if p.ndim != 3:
        raise ValueError("result: snapshots need a dynamic result (with a time axis)")
    idx = np.unique(np.linspace(0, p.shape[0] - 1, count).round().astype(int))
    kwargs.setdefault("colorbar_label", "time [s]")
    return plot_configurations(p[idx], R[idx], values=result.time[idx], **kwargs)


def plot_result_tip(result, rod, *, displacement=True, **kwargs):
    """:func:`plot_tip_trajectory` of the last node of ``rod`` in a dynamic Result:
    its displacement from the start (m, the paper's Figs. 6-8) or, with
    ``displacement=False``, its position."""
    p = result.positions(rod)
    if p.ndim != 3:
        raise ValueError("result: a tip trajectory needs a dynamic result (with a time axis)")
    tip = p[:, -1] - p[0, -1] if displacement else p[:, -1]
    kwargs.setdefault("ylabel", "tip displacement [m]" if displacement else "tip position [m]")
    return plot_tip_trajectory(result.time, tip, **kwargs)


def animate_result(result, rod, path, *, samples_per_element=6, **kwargs):
    """:func:`animate_rod` of ``rod`` in a dynamic Result; returns the written path."""
    p, R = sample_result(result, rod, samples_per_element)
    if p.ndim != 3:
        raise ValueError("result: an animation needs a dynamic result (with a time axis)")
    kwargs.setdefault("title", result.name or rod)
    return animate_rod(p, path, R, time=result.time, **kwargs)
