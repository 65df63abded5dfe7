"""Tests of bondid.plots: PNGs are written and not blank, and the drawn data are the input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bondid.exceptions import ChannelError, ConfigError, DataError
from bondid.plots import (
    Curve,
    build_bode,
    build_residual_map,
    build_sweep,
    plot_bode,
    plot_convergence,
    plot_heatmap,
    plot_residual_map,
    plot_sweep,
    rank_parameters,
)
from bondid.plots.bode import channel_unit

OUT = ("x", "y")
F = np.logspace(0, 3, 60)


def _frf(scale: float = 1.0) -> np.ndarray:
    """Receptance (2, 2, 60) of a 2-DOF chain, m/N."""
    w = 2 * np.pi * F
    M = np.diag([2.0, 1.0]) * scale
    K = np.array([[3e5, -1e5], [-1e5, 1e5]])
    D = np.array([[30.0, -10.0], [-10.0, 10.0]])
    Z = K[None] - (w**2)[:, None, None] * M[None] + 1j * w[:, None, None] * D[None]
    return np.moveaxis(np.linalg.inv(Z), 0, -1)


def _assert_png(path: Path) -> None:
    from matplotlib.image import imread

    assert path.is_file()
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    assert float(np.var(img[..., :3])) > 1e-3  # not a blank canvas
    assert not list(path.parent.glob(f".{path.name}.*"))  # no temporary file left


def test_import_is_light() -> None:
    code = "import sys, bondid.plots; print(any(m.startswith('matplotlib') for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_bode_png_axes_and_magnitude(tmp_path: Path) -> None:
    H = _frf()
    meas = Curve("measured", H, kind="measured")
    model = Curve("model", _frf(1.1))
    fig = build_bode(F, [meas, model], outputs=OUT, inputs=OUT, units={"x": "m", "y": "rad"})
    axes = fig.get_axes()
    assert len(axes) == 2 * 4  # magnitude + phase per cell of the 2 × 2 grid
    ax_mag, ax_ph = axes[2], axes[3]  # cell x.y (row 0, column 1)
    assert ax_mag.get_title() == "x.y"
    assert ax_mag.get_ylabel() == "receptance [dB re 1 m/(N·m)]"
    mag = ax_mag.get_lines()[0]
    np.testing.assert_allclose(mag.get_xdata(), F)
    np.testing.assert_allclose(mag.get_ydata(), 20 * np.log10(np.abs(H[0, 1])), rtol=1e-12)
    ph = np.asarray(ax_ph.get_lines()[1].get_ydata(), dtype=float)
    ph = ph[np.isfinite(ph)]
    assert ph.min() >= -180.0 and ph.max() <= 180.0
    assert ph.size == F.size  # every point drawn, only NaN breaks were added
    out = plot_bode(F, [meas, model], outputs=OUT, inputs=OUT, path=tmp_path / "b.png")
    assert out == tmp_path / "b.png"
    _assert_png(out)


def test_bode_phase_wraps_without_vertical_strokes() -> None:
    h = np.exp(1j * np.linspace(0, 6 * np.pi, F.size))[None, None, :]
    fig = build_bode(F, [Curve("c", h)], outputs=("a",), inputs=("b",))
    y = np.asarray(fig.get_axes()[1].get_lines()[0].get_ydata(), dtype=float)
    steps = np.abs(np.diff(y))
    assert np.nanmax(steps) < 180.0  # the ±180° jumps are broken by NaN, not drawn
    # phase 0 → 6π crosses +180° at π, 3π and 5π: three wraps, each broken by one NaN
    assert np.count_nonzero(np.isnan(y)) == 3


def test_bode_missing_channel_and_subset(tmp_path: Path) -> None:
    H = _frf()
    H[1, 0] = np.nan
    fig = build_bode(F, [Curve("m", H, kind="measured")], outputs=OUT, inputs=OUT)
    marked = [
        ax.get_title() for ax in fig.get_axes() for t in ax.texts if t.get_text() == "no data"
    ]
    assert marked == ["y.x"]
    other = Curve("coarse", _frf(0.9)[:, :, ::3], freq_hz=F[::3])
    fig = build_bode(F, [other], outputs=OUT, inputs=OUT, channels=["y.y", "x.x"])
    axes = fig.get_axes()
    assert len(axes) == 4 and [axes[0].get_title(), axes[2].get_title()] == ["y.y", "x.x"]
    assert axes[0].get_lines()[0].get_xdata().size == F[::3].size
    with pytest.raises(ChannelError, match=r"z\.x"):
        build_bode(F, [other], outputs=OUT, inputs=OUT, channels=["z.x"])
    with pytest.raises(DataError, match="shape"):
        build_bode(F, [Curve("bad", H[:, :, :10])], outputs=OUT, inputs=OUT)
    with pytest.raises(ConfigError):
        plot_bode(F, [other], outputs=OUT, inputs=OUT, path=tmp_path / "b.jpg")


def test_channel_unit() -> None:
    units = {"x": "m", "t": "rad"}
    assert channel_unit(units, "x", "x") == "m/N"
    assert channel_unit(units, "t", "x") == "rad/N"
    assert channel_unit(units, "x", "t", "mobility") == "(m/s)/(N·m)"
    assert channel_unit({"x": "N"}, "x", "x", "accelerance") == "(m/s²)/N"
    assert channel_unit(units, "x", "q") is None


def test_residual_map_symmetric_limits(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    r = rng.normal(1.5, 2.0, (3, F.size))
    r[2] = np.nan
    fig = build_residual_map(F, r, channels=["x.x", "x.y", "y.y"], bands=[(1, 30), (30, 1000)])
    mesh = fig.get_axes()[0].collections[0]
    lo, hi = mesh.get_clim()
    assert lo == pytest.approx(-hi) and hi > 0
    ax = fig.get_axes()[0]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["x.x", "x.y", "y.y"]
    assert any(t.get_text() == "no data" for t in ax.texts)
    fig = build_residual_map(F, r, channels=["a", "b", "c"], vmax=7.0)
    assert fig.get_axes()[0].collections[0].get_clim() == (-7.0, 7.0)
    _assert_png(plot_residual_map(F, r, channels=["a", "b", "c"], path=tmp_path / "r.png"))
    with pytest.raises(DataError, match="n_channels"):
        build_residual_map(F, r, channels=["a", "b"])


def test_heatmap_png(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    v = 10 ** rng.uniform(-3, 1, (70, 4))
    names = [f"p{k:02d}.stiffness" for k in range(70)]
    _assert_png(
        plot_heatmap(
            v,
            row_labels=names,
            col_labels=["B1", "B2", "B3", "B4"],
            path=tmp_path / "h.png",
            log=True,
            cbar_label="|S|",
        )
    )
    _assert_png(
        plot_heatmap(
            v[:3, :2] - 1,
            row_labels=["a", "b", "c"],
            col_labels=["u", "v"],
            path=tmp_path / "h2.png",
        )
    )
    with pytest.raises(DataError, match="shape"):
        plot_heatmap(v, row_labels=names[:3], col_labels=["B1"], path=tmp_path / "x.png")


def test_convergence_png(tmp_path: Path) -> None:
    _assert_png(plot_convergence([10.0, 3.0, 1.0, 0.5, 0.4], path=tmp_path / "c1.png"))
    runs = [np.geomspace(10, 0.1 * (k + 1), 8 + k) for k in range(4)]
    _assert_png(plot_convergence(runs, path=tmp_path / "c4.png", labels=list("abcd")))
    with pytest.raises(DataError, match="labels"):
        plot_convergence(runs, path=tmp_path / "c.png", labels=["a"])


def test_sweep_highlights_most_influential(tmp_path: Path) -> None:
    scales = np.linspace(0.5, 1.5, 5)
    weights = np.array([0.1, 5.0, 0.01, 2.0, 0.5, 3.0])
    costs = 1.0 + weights[:, None] * (scales - 1.0) ** 2
    names = [f"p{k}" for k in range(6)]
    assert rank_parameters(costs, 3).tolist() == [1, 5, 3]
    fig = build_sweep(scales, costs, param_names=names, top=3)
    ax = fig.get_axes()[0]
    top = [ln.get_label() for ln in ax.get_lines() if str(ln.get_gid()).startswith("top:")]
    rest = [ln.get_gid() for ln in ax.get_lines() if str(ln.get_gid()).startswith("rest:")]
    assert sorted(top) == ["p1", "p3", "p5"]
    assert sorted(rest) == ["rest:p0", "rest:p2", "rest:p4"]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["p1", "p5", "p3"]
    # one panel per direction, each ranked on its own costs
    costs3 = np.stack([costs, costs[::-1]])
    fig = build_sweep(scales, costs3, param_names=names, top=1, direction_names=["x", "y"])
    axes = fig.get_axes()
    assert len(axes) == 2
    assert [t.get_text() for t in axes[1].get_legend().get_texts()] == ["p4"]
    assert axes[1].get_title(loc="left").startswith("y:")
    _assert_png(plot_sweep(scales, costs3, param_names=names, path=tmp_path / "s.png", top=2))
    with pytest.raises(DataError, match="n_params"):
        build_sweep(scales, costs[:, :3], param_names=names)
