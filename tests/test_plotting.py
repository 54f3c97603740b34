"""simsoft_jax.plotting on tiny inputs: every function returns a Figure (or writes a
non-empty GIF), rejects wrong shapes with a ValueError naming the argument, draws the
section ribbon along the requested local axis of the rotations, keeps 3-D axes equally
scaled, and the Result helpers draw the helical interpolation (an exact circle for
constant curvature, spec S74). The helpers are fed a stand-in with the Result interface
(positions, rotations, time, name) so that no solver is compiled here."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib import animation  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from simsoft_jax import plotting  # noqa: E402
from conftest import arc, rot_x, rot_y  # noqa: E402


def twisted_rod(n=4, length=1.0, twist=np.pi / 2):
    """A straight rod along x whose sections turn about x by up to ``twist`` (rad)."""
    s = np.linspace(0.0, length, n)
    p = np.stack([s, 0 * s, 0 * s], axis=1)
    R = np.stack([rot_x(twist * si / length) for si in s])
    return p, R


class StubResult:
    """The part of :class:`simsoft_jax.Result` the plotting helpers use."""

    def __init__(self, p, R, time=None):
        self.name, self.time, self._p, self._R = "stub", time, p, R

    def positions(self, rod):
        assert rod == "arm"
        return self._p.copy()

    def rotations(self, rod):
        assert rod == "arm"
        return self._R.copy()


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def lines_by_gid(fig, gid):
    return [line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == gid]


# ------------------------------------------------------------------------------- ribbons

@pytest.mark.parametrize("axis", [1, 2])
def test_ribbon_follows_the_section_axis(axis):
    p, R = twisted_rod()
    width = 0.1
    fig = plotting.plot_rod(p, R, width=width, axis=axis)
    assert isinstance(fig, Figure)
    (minus,), (plus,) = lines_by_gid(fig, "ribbon_minus"), lines_by_gid(fig, "ribbon_plus")
    minus, plus = np.array(minus.get_data_3d()).T, np.array(plus.get_data_3d()).T
    # the drawn edges are p -/+ (w/2) R[:, axis]: their offset is w R[:, :, axis]
    np.testing.assert_allclose(plus - minus, width * R[:, :, axis], atol=1e-15)
    np.testing.assert_allclose(0.5 * (plus + minus), p, atol=1e-15)
    # e.g. the tip section turned by 90 deg about x: local y is world z, local z is -y
    expected_tip = {1: [0.0, 0.0, width], 2: [0.0, -width, 0.0]}[axis]
    np.testing.assert_allclose(plus[-1] - minus[-1], expected_tip, atol=1e-15)
    quads = plotting.ribbon_vertices(p, R, width, axis)
    assert quads.shape == (len(p) - 1, 4, 3)
    np.testing.assert_allclose(quads[:, 1] - quads[:, 0], width * R[:-1, :, axis], atol=1e-15)


def test_triads_and_equal_aspect():
    p, R = twisted_rod()
    fig = plotting.plot_rod(p, R, triads=True, label="rod", title="t")
    ax = fig.axes[0]
    spans = [np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())]
    assert spans == pytest.approx([spans[0]] * 3)          # equal scaling of x, y, z
    box = np.asarray(ax.get_box_aspect())
    assert box == pytest.approx(np.full(3, box[0]))        # a cubic box
    colours = {line.get_color() for line in ax.get_lines()}
    assert set(plotting.TRIAD_COLORS) <= colours


@pytest.mark.parametrize("call, name", [
    (lambda p, R: plotting.plot_rod(p[:, :2]), "positions"),
    (lambda p, R: plotting.plot_rod(p[:1]), "positions"),
    (lambda p, R: plotting.plot_rod(p, R[:-1]), "rotations"),
    (lambda p, R: plotting.plot_rod(p, R[:, :2]), "rotations"),
    (lambda p, R: plotting.plot_rod(p * np.nan), "positions"),
    (lambda p, R: plotting.ribbon_vertices(p, R, 0.0), "width"),
    (lambda p, R: plotting.ribbon_vertices(p, R, 0.1, axis=3), "axis"),
    (lambda p, R: plotting.ribbon_vertices(p, R, 0.1, axis=0), "axis"),
    (lambda p, R: plotting.plot_configurations(p, R), "positions"),
    (lambda p, R: plotting.plot_configurations(p[None], R), "rotations"),
    (lambda p, R: plotting.plot_configurations(p[None], labels=["a", "b"]), "labels"),
    (lambda p, R: plotting.plot_configurations(p[None], values=[1.0, 2.0]), "values"),
    (lambda p, R: plotting.plot_configurations(p[None], references=p), "references"),
    (lambda p, R: plotting.plot_tip_trajectory([0.0, 1.0], p), "tip"),
    (lambda p, R: plotting.plot_tip_trajectory(p, p), "time"),
    (lambda p, R: plotting.plot_tip_trajectory(np.arange(4.0), p, reference=p[:2]),
     "reference"),
    (lambda p, R: plotting.plot_error_bars([0, 15], [[1.0]], [[0.1]]), "mean"),
    (lambda p, R: plotting.plot_error_bars([0], [[1.0, 2.0]], [[0.1]]), "std"),
    (lambda p, R: plotting.plot_work_precision({"a": ([1.0, 2.0], [1e-2])}), "errors"),
    (lambda p, R: plotting.plot_work_precision({"a": ([1.0, 2.0], [1e-2, 0.0])}),
     "series"),
])
def test_wrong_inputs_name_the_argument(call, name):
    p, R = twisted_rod()
    with pytest.raises(ValueError, match=name):
        call(p, R)


# ---------------------------------------------------------------- overlays, trajectories

def test_configurations_with_labels_references_or_colorbar():
    s = np.linspace(0.0, 1.0, 5)
    shapes = [arc(k, s) for k in (1.0, 2.0, 3.0)]
    p, R = np.stack([a for a, _ in shapes]), np.stack([b for _, b in shapes])
    fig = plotting.plot_configurations(p, R, labels=["1", "2", "3"], references=p + 0.01)
    assert isinstance(fig, Figure)
    assert len(lines_by_gid(fig, "ribbon_plus")) == 3
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert texts == ["1", "2", "3", "exact"]
    fig = plotting.plot_configurations(p, values=[0.0, 0.5, 1.0], colorbar_label="t [s]")
    assert len(fig.axes) == 2 and fig.axes[1].get_ylabel() == "t [s]"   # the colorbar
    # colours follow the colormap in the order of the values
    first, last = (fig.axes[0].get_lines()[i].get_color() for i in (0, -1))
    assert np.allclose(matplotlib.colors.to_rgba(first), plt.colormaps["viridis"](0.0))
    assert np.allclose(matplotlib.colors.to_rgba(last), plt.colormaps["viridis"](1.0))


def test_tip_trajectory_draws_each_component():
    t = np.linspace(0.0, 1.0, 11)
    tip = np.stack([np.cos(t), np.sin(t), t], axis=1)
    fig = plotting.plot_tip_trajectory(t, tip, title="tip")
    lines = fig.axes[0].get_lines()
    assert len(lines) == 3
    for k, line in enumerate(lines):
        np.testing.assert_array_equal(line.get_ydata(), tip[:, k])
    fig = plotting.plot_tip_trajectory(t, tip, reference=tip + 1.0)
    assert len(fig.axes[0].get_lines()) == 6


# ---------------------------------------------------------------------------- animations

def test_animation_writes_a_gif(tmp_path):
    p, R = twisted_rod()
    frames = np.stack([p + [0.0, 0.0, 0.1 * k] for k in range(3)])
    path = plotting.animate_rod(frames, tmp_path / "rod.gif", np.stack([R] * 3),
                                time=[0.0, 0.1, 0.2], fps=5)
    data = path.read_bytes()
    assert data[:6] in (b"GIF87a", b"GIF89a") and len(data) > 1000
    with pytest.raises(ValueError, match="path"):
        plotting.animate_rod(frames, tmp_path / "rod.avi")
    with pytest.raises(ValueError, match="time"):
        plotting.animate_rod(frames, tmp_path / "rod.gif", time=[0.0])
    if not animation.FFMpegWriter.isAvailable():
        with pytest.raises(RuntimeError, match="ffmpeg"):
            plotting.animate_rod(frames, tmp_path / "rod.mp4")


def test_gif_frames_show_the_motion(tmp_path):
    """Each frame is drawn once over the same background: the GIF holds one frame per
    state, the red tip marker rises frame by frame as the rod is lifted (image rows grow
    downwards), and the background corner is the same pixel in every frame."""
    from PIL import Image
    p, R = twisted_rod(n=5)
    lifts = [0.0, 0.2, 0.4, 0.6]
    frames = np.stack([p + [0.0, 0.0, dz] for dz in lifts])
    path = plotting.animate_rod(frames, tmp_path / "lift.gif", np.stack([R] * len(lifts)),
                                time=lifts, fps=4)
    rows, corners = [], []
    with Image.open(path) as gif:
        assert gif.n_frames == len(lifts)
        assert gif.info["duration"] == 250          # ms per frame at 4 frames per second
        for k in range(gif.n_frames):
            gif.seek(k)
            rgb = np.asarray(gif.convert("RGB")).astype(int)
            red = (rgb[..., 0] > 180) & (rgb[..., 1] < 90) & (rgb[..., 2] < 90)
            assert red.sum() > 5, f"frame {k}: no tip marker"
            rows.append(np.nonzero(red)[0].mean())
            corners.append(tuple(rgb[2, 2]))
    assert np.all(np.diff(rows) < -3.0), rows
    assert len(set(corners)) == 1


# ------------------------------------------------------------------------- error figures

def test_error_bars_grouped_by_angle():
    """Seed Figs. 16-18 style: one group per angle, one bar per load case, std as error
    bar; groups may hold different numbers of load cases."""
    mean = [[0.1, 0.2, 0.3, 0.4], [0.15, 0.25, 0.35]]
    std = [[0.01, 0.02, 0.03, 0.04], [0.05, 0.06, 0.07]]
    fig = plotting.plot_error_bars([0, 45], mean, std, case_labels=["f0", "2f0", "3f0", "4f0"])
    ax = fig.axes[0]
    heights = sorted(patch.get_height() for patch in ax.patches)
    assert heights == pytest.approx(sorted(sum(mean, [])))
    error_bars = [c for c in ax.containers if isinstance(c, matplotlib.container.ErrorbarContainer)]
    segments = np.concatenate([c.lines[2][0].get_segments() for c in error_bars])
    lengths = sorted(np.ptp(seg[:, 1]) for seg in segments)
    assert lengths == pytest.approx(sorted(2 * np.array(sum(std, []))))   # mean -/+ std
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "45"]


def test_work_precision_is_log_log():
    fig = plotting.plot_work_precision({"a": ([1e-3, 1e-2], [1e-2, 1e-4]),
                                        "b": ([2e-3, 3e-2], [1e-3, 1e-6])})
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert len(ax.get_lines()) == 2


# ---------------------------------------------------------------------- Result helpers

def test_static_result_helper_draws_the_helical_interpolation():
    """Pure-bending nodes (2 elements, exact arc of curvature 2 1/m about y): the drawn
    centreline, the helical interpolation between the nodes (seed eq. 27), lies on the
    exact circle of radius 1/2 m. (Real Results from ``sj.run`` go through these helpers
    in tests/test_examples.py and tests/test_notebooks.py.)"""
    kappa = 2.0
    p, R = arc(kappa, np.linspace(0.0, 1.0, 3))
    stub = StubResult(p, R)
    fig = plotting.plot_result(stub, "arm", samples_per_element=5)
    centreline = np.array(fig.axes[0].get_lines()[0].get_data_3d()).T
    assert centreline.shape == (11, 3)
    centre = np.array([0.0, 0.0, -1.0 / kappa])
    np.testing.assert_allclose(np.linalg.norm(centreline - centre, axis=1), 1.0 / kappa,
                               atol=1e-12)
    np.testing.assert_allclose(centreline[::5], p, atol=1e-14)     # through the nodes
    for helper in (plotting.plot_result_tip, plotting.plot_result_snapshots):
        with pytest.raises(ValueError, match="result"):
            helper(stub, "arm")


def test_dynamic_result_helpers(tmp_path):
    """Snapshots, tip trajectory and animation of a (T, N) result: a rigid rotation of
    an exact arc about y; the sampled frames stay on the rotated circle."""
    s = np.linspace(0.0, 1.0, 4)
    p, R = arc(2.0, s)
    time = np.linspace(0.0, 1.0, 5)
    turns = [rot_y(0.3 * t) for t in time]
    stub = StubResult(np.stack([p @ Q.T for Q in turns]), np.stack([Q @ R for Q in turns]),
                      time)
    ps, Rs = plotting.sample_result(stub, "arm", 4)
    assert ps.shape == (5, 13, 3) and Rs.shape == (5, 13, 3, 3)
    for k, Q in enumerate(turns):
        centre = Q @ np.array([0.0, 0.0, -0.5])
        np.testing.assert_allclose(np.linalg.norm(ps[k] - centre, axis=1), 0.5, atol=1e-12)
    fig = plotting.plot_result_snapshots(stub, "arm", 3)
    assert len(lines_by_gid(fig, "ribbon_plus")) == 3
    fig = plotting.plot_result_tip(stub, "arm")
    np.testing.assert_allclose(fig.axes[0].get_lines()[0].get_ydata(),
                               stub.positions("arm")[:, -1, 0] - p[-1, 0], atol=1e-15)
    path = plotting.animate_result(stub, "arm", tmp_path / "stub.gif", max_frames=3)
    assert path.stat().st_size > 1000
