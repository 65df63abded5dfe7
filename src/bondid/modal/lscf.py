"""Numerical core of the modal identification: poly-reference LSCF, stabilisation, LSFD.

Poly-reference least-squares complex-frequency (pLSCF) estimator on one frequency band:
each output row of the (scaled) FRF is modelled as a right matrix-fraction
``H_o(ω) = N_o(z) D(z)⁻¹`` with ``z = exp(j ω Δt)``, ``Δt = π / ω_max`` (the band's top
frequency maps to the Nyquist angle), real matrix-polynomial coefficients and the highest
denominator coefficient fixed to the identity. The linearised equation error
``w_o(ω) [N_o(z) − H_o(ω) D(z)]`` is minimised in least squares; the numerator coefficients
are eliminated (reduced normal equations), so one small symmetric system of size
``(n+1)·n_in`` gives the denominator of every order ``n ≤ n_max`` at once. The poles of order
``n`` are the eigenvalues ``z_p`` of the block companion matrix of ``D`` (``n·n_in`` of them),
``λ = ln(z_p) / Δt`` [1/s].

LSFD (least-squares frequency domain): given poles, the residues follow per channel from a
linear least-squares fit of ``Σ_r R_r/(s − λ_r) + R̄_r/(s − λ̄_r) + L₁/s + L₂/s² + L₃/s³ + U``
(real ``L₁..L₃``, ``U``: lower and upper residual terms; the ``1/s`` series is the
Laurent expansion of the rigid-body mass lines and of poles far below the band), with
relative weighting ``1/|H|``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PoleSet:
    """Poles of one model order: ``lam`` (n_p,) [1/s], ``order`` n."""

    order: int
    lam: np.ndarray


def plscf(
    freq_hz: np.ndarray,
    H: np.ndarray,
    weight: np.ndarray,
    n_max: int,
) -> list[PoleSet]:
    """pLSCF poles for every order ``1..n_max`` on one band.

    Args:
        freq_hz: ``(n_f,)`` [Hz], the band's frequencies.
        H: ``(n_out, n_in, n_f)`` complex, scaled so channels are of comparable size.
        weight: ``(n_out, n_f)`` real weights of each output row's equation error.
        n_max: highest polynomial order.

    Returns:
        One :class:`PoleSet` per order (upper-half-plane and real poles alike).
    """
    n_out, n_in, n_f = H.shape
    w = 2 * np.pi * np.asarray(freq_hz, dtype=float)
    dt = np.pi / w[-1]
    zb = np.exp(1j * np.outer(w * dt, np.arange(n_max + 1)))  # (n_f, n+1)
    K = (n_max + 1) * n_in
    M_parts = []
    for o in range(n_out):
        G = weight[o][:, None] * zb  # (n_f, n+1)
        Hw = H[o].T  # (n_f, n_in)
        U = (G[:, :, None] * Hw[:, None, :]).reshape(n_f, K)  # r major, j minor
        M_parts.append(
            (
                np.real(G.conj().T @ G),
                np.real(G.conj().T @ U),
                np.real(U.conj().T @ U),
            )
        )
    out = []
    for n in range(1, n_max + 1):
        k = (n + 1) * n_in
        M = np.zeros((k, k))
        for R, S, T in M_parts:
            Rn, Sn = R[: n + 1, : n + 1], S[: n + 1, :k]
            M += T[:k, :k] - Sn.T @ np.linalg.lstsq(Rn, Sn, rcond=None)[0]
        a = n * n_in
        try:
            alpha_a = -np.linalg.solve(M[:a, :a], M[:a, a:])
        except np.linalg.LinAlgError:
            alpha_a = -np.linalg.lstsq(M[:a, :a], M[:a, a:], rcond=None)[0]
        # alpha_a rows: (r, j) r major; block r is alpha_r (n_in x n_in)
        comp = np.zeros((a, a))
        if n > 1:
            comp[: a - n_in, n_in:] = np.eye(a - n_in)
        comp[a - n_in :, :] = -alpha_a.reshape(n, n_in, n_in).transpose(1, 0, 2).reshape(n_in, a)
        zp = np.linalg.eigvals(comp)
        zp = zp[np.abs(zp) > 0]
        out.append(PoleSet(n, np.log(zp.astype(complex)) / dt))
    return out


def physical(lam: np.ndarray, f_lo: float, f_hi: float, zeta_max: float) -> np.ndarray:
    """Mask of poles with Im λ > 0, 0 < ζ < zeta_max and f = |λ|/2π in [f_lo, f_hi)."""
    f = np.abs(lam) / (2 * np.pi)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = -lam.real / np.abs(lam)
    return (lam.imag > 0) & (zeta > 0) & (zeta < zeta_max) & (f >= f_lo) & (f < f_hi)


def stable_clusters(
    poles: list[PoleSet],
    f_lo: float,
    f_hi: float,
    *,
    zeta_max: float,
    tol_f: float,
    tol_zeta: float,
    min_count: int,
) -> list[tuple[complex, int]]:
    """Physical poles that stay put from order to order (the stabilisation diagram).

    Poles are followed as tracks: a physical pole of order n continues the track of the
    nearest physical pole of order n−1 when it lies within ``tol_f`` (relative) in frequency
    and ``tol_zeta`` (relative) in damping (one pole per track and order, the nearest wins);
    otherwise it starts a new track. A track spanning at least ``min_count`` orders is a
    mode; its pole is the median frequency and damping over the last half of the track (the
    higher orders, where the estimate has settled). Tracks of the same mode broken by a
    missed order are merged later by the caller.

    Returns:
        ``[(λ, n_orders), ...]`` by frequency.
    """
    tracks: list[list[tuple[float, float]]] = []
    open_: dict[int, tuple[float, float]] = {}  # track index -> its pole at order n-1
    for ps in poles:
        lam = ps.lam[physical(ps.lam, f_lo, f_hi, zeta_max)]
        f = np.abs(lam) / (2 * np.pi)
        z = -lam.real / np.abs(lam)
        links = _links(open_, f, z, tol_f, tol_zeta)
        nxt: dict[int, tuple[float, float]] = {}
        linked = {k for _, k in links.values()}
        for t, (_, k) in links.items():
            tracks[t].append((float(f[k]), float(z[k])))
            nxt[t] = (float(f[k]), float(z[k]))
        for k in range(f.size):
            if k not in linked:
                tracks.append([(float(f[k]), float(z[k]))])
                nxt[len(tracks) - 1] = (float(f[k]), float(z[k]))
        open_ = nxt
    result = [(_settled_pole(tr), len(tr)) for tr in tracks if len(tr) >= min_count]
    result.sort(key=lambda c: abs(c[0]))
    return result


def _links(
    open_: dict[int, tuple[float, float]],
    f: np.ndarray,
    z: np.ndarray,
    tol_f: float,
    tol_zeta: float,
) -> dict[int, tuple[float, int]]:
    """Which poles (``f`` [Hz], ``z`` damping ratios) continue which open tracks (``open_``:
    track → its last ``(f, ζ)``): ``{track: (distance, pole index)}``, each pole linked to the
    nearest track within the tolerances, each track keeping its nearest pole."""
    links: dict[int, tuple[float, int]] = {}
    for k in range(f.size):
        best, best_d = None, np.inf
        for t, (fp, zp) in open_.items():
            df, dz = abs(f[k] - fp) / f[k], abs(z[k] - zp) / z[k]
            if df < tol_f and dz < tol_zeta:
                dist = df / tol_f + dz / tol_zeta
                if dist < best_d:
                    best, best_d = t, dist
        if best is not None and (best not in links or best_d < links[best][0]):
            links[best] = (best_d, k)
    return links


def _settled_pole(track: list[tuple[float, float]]) -> complex:
    """λ of a track of ``(f, ζ)``: the median frequency and damping over its last half."""
    tail = track[len(track) // 2 :]
    fm = float(np.median([p[0] for p in tail]))
    zm = float(np.median([p[1] for p in tail]))
    w = 2 * np.pi * fm
    return complex(-zm * w, w * np.sqrt(1.0 - zm * zm))


def lsfd(
    freq_hz: np.ndarray,
    H: np.ndarray,
    lam: np.ndarray,
    weight: np.ndarray | None = None,
    *,
    lower: bool = True,
    upper: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Residues of given poles by weighted linear least squares, channel by channel.

    Args:
        freq_hz: ``(n_f,)`` [Hz].
        H: ``(n_out, n_in, n_f)`` complex (NaN channels give NaN residues).
        lam: ``(n_m,)`` poles [1/s], Im λ > 0 (each stands for its conjugate pair).
        weight: ``(n_out, n_in, n_f)`` extra real weights (multiplied with ``1/|H|``).
        lower: include the lower residual terms ``L₁/s + L₂/s² + L₃/s³``.
        upper: number of upper residual terms ``U₀ + U₁ s + …`` (0 = none).

    Returns:
        ``(R, model)``: residues ``(n_m, n_out, n_in)`` complex (FRF units × 1/s) and the
        fitted FRF ``(n_out, n_in, n_f)``.
    """
    s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
    cols = []
    for lr in lam:
        a = 1.0 / (s - lr)
        b = 1.0 / (s - np.conj(lr))
        cols += [a + b, 1j * (a - b)]
    n_modal = len(cols)
    if lower:
        cols += [1.0 / s, 1.0 / s**2, 1.0 / s**3]
    cols += [s**k for k in range(int(upper))]
    A = np.stack(cols, axis=1)  # (n_f, n_c)
    n_out, n_in, n_f = H.shape
    n_c = A.shape[1]
    h = H.reshape(n_out * n_in, n_f)
    ok = np.isfinite(h) & (np.abs(h) > 0)
    wt = np.zeros(h.shape)
    wt[ok] = 1.0 / np.abs(h[ok])
    if weight is not None:
        wt = wt * np.nan_to_num(weight.reshape(h.shape))
    good = np.count_nonzero(ok, axis=1) >= n_c
    Aw = A[None, :, :] * wt[:, :, None]  # (n_ch, n_f, n_c)
    Ar = np.concatenate([Aw.real, Aw.imag], axis=1)
    hw = np.where(ok, h, 0.0) * wt
    br = np.concatenate([hw.real, hw.imag], axis=1)
    scale = np.linalg.norm(Ar, axis=1)  # (n_ch, n_c)
    scale[scale == 0] = 1.0
    # R factor of [A b]: its last column holds Qᵀb, so Q is never formed
    Rfull: np.ndarray = np.linalg.qr(  # type: ignore[assignment]
        np.concatenate([Ar / scale[:, None, :], br[:, :, None]], axis=2), "r"
    )
    Rq, rhs = Rfull[:, :n_c, :n_c], Rfull[:, :n_c, n_c]
    x = np.full((h.shape[0], n_c), np.nan)
    for k in np.flatnonzero(good):  # small triangular systems; least squares if singular
        x[k] = np.linalg.lstsq(Rq[k], rhs[k], rcond=1e-13)[0] / scale[k]
    R = (x[:, :n_modal:2] + 1j * x[:, 1:n_modal:2]).T.reshape(len(lam), n_out, n_in)
    model = (x @ A.T).reshape(H.shape)
    return R, model


def mode_terms(freq_hz: np.ndarray, lam: complex, R: np.ndarray) -> np.ndarray:
    """One mode's FRF terms ``R/(s−λ) + R̄/(s−λ̄)``, shape ``(*R.shape, n_f)``."""
    s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
    return R[..., None] / (s - lam) + np.conj(R)[..., None] / (s - np.conj(lam))


def _weighted_error(H: np.ndarray, model: np.ndarray, weight: np.ndarray | None) -> np.ndarray:
    ok = np.isfinite(H) & np.isfinite(model) & (np.abs(H) > 0)
    e = (model[ok] - H[ok]) / np.abs(H[ok])
    if weight is not None:
        e = e * weight[ok]
    return np.concatenate([e.real, e.imag])


def refine_poles(
    freq_hz: np.ndarray,
    H: np.ndarray,
    lam: np.ndarray,
    free: np.ndarray,
    weight: np.ndarray | None = None,
    *,
    zeta_max: float = 0.3,
    max_shift: float = 0.05,
    upper: int = 2,
) -> np.ndarray:
    """Polish the ``free`` poles by nonlinear least squares on the FRF itself.

    Variable projection: for trial poles the residues and residual terms follow from
    :func:`lsfd`; the relative (``1/|H|``-weighted) error is minimised over ``ln ω_n`` and
    ``ln ζ`` of the free poles (scipy ``least_squares``, finite differences). A refined pole
    that moves by more than ``max_shift`` (relative) in frequency, or leaves
    ``0 < ζ < zeta_max``, is put back to its start value.

    Returns:
        ``(n_m,)`` poles [1/s].
    """
    from scipy.optimize import least_squares

    lam = np.asarray(lam, dtype=complex).copy()
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return lam
    wn0, z0 = np.abs(lam[idx]), -lam[idx].real / np.abs(lam[idx])

    def poles(x: np.ndarray) -> np.ndarray:
        out = lam.copy()
        wn, z = np.exp(x[: idx.size]), np.minimum(np.exp(x[idx.size :]), 0.999)
        out[idx] = -z * wn + 1j * wn * np.sqrt(1.0 - z * z)
        return out

    def fun(x: np.ndarray) -> np.ndarray:
        _, model = lsfd(freq_hz, H, poles(x), weight, upper=upper)
        return _weighted_error(H, model, weight)

    x0 = np.concatenate([np.log(wn0), np.log(z0)])
    try:
        sol = least_squares(fun, x0, method="lm", x_scale=1.0, max_nfev=15 * (x0.size + 1))
        x = sol.x
    except (ValueError, np.linalg.LinAlgError):
        return lam
    new = poles(x)
    wn, z = np.abs(new[idx]), -new[idx].real / np.abs(new[idx])
    bad = (np.abs(wn / wn0 - 1.0) > max_shift) | (z <= 0) | (z >= zeta_max)
    new[idx[bad]] = lam[idx[bad]]
    return new


def balance(c: np.ndarray, iters: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Row and column scales making the typical magnitudes ``c`` (n_out, n_in) comparable."""
    c = np.where(np.isfinite(c) & (c > 0), c, np.nan)
    r, t = np.ones(c.shape[0]), np.ones(c.shape[1])
    for _ in range(iters):
        m = r[:, None] * c * t[None, :]
        r = r / np.sqrt(np.nanmean(m**2, axis=1))
        m = r[:, None] * c * t[None, :]
        t = t / np.sqrt(np.nanmean(m**2, axis=0))
    return np.nan_to_num(r, nan=1.0), np.nan_to_num(t, nan=1.0)


def band_plan(f: np.ndarray, ratio: float, overlap: float) -> list[tuple[float, float]]:
    """Core bands (geometric, about ``ratio`` wide) covering ``[f[0], f[-1]]``."""
    n = max(1, round(np.log(f[-1] / f[0]) / np.log(ratio)))
    edges = np.geomspace(f[0], f[-1], n + 1)
    edges[-1] = np.nextafter(f[-1], np.inf)
    return [(float(edges[k]), float(edges[k + 1])) for k in range(n)]
