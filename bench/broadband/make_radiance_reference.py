#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Broadband 1-D reference radiances of the U.S. Standard Atmosphere 1976 column, clear and
with a gray cloud layer (shortwave and longwave), for kumo's broadband layer, computed
independently of kumo.

Inputs: the per-g-point optics of the column `us1976` stored in
tests/data/broadband/sw_gpoint_reference.txt (112 g-points: absorption and Rayleigh optical depth
of every layer, TOA solar flux of every g-point, mu0, albedo, TSI) and
tests/data/broadband/lw_gpoint_reference.txt (128 g-points: absorption optical depth, Planck
sources at the bottom and top of every layer and at the surface, surface temperature and
emissivity); gas optics are not recomputed. The cloudy column `us1976_cloud` takes the cloud
(`cloud` line) of tests/data/broadband/sw_cloudy_reference.txt and lw_cloudy_reference.txt
(bench/broadband/make_cloudy_reference.py), whose broadband fluxes serve as a check. Output:
tests/data/broadband/radiance_reference.txt.

Method. Every g-point is solved with the discrete-ordinates code PythonicDISORT (PyPI
`PythonicDISORT`, D. J. Ho 2024, J. Open Source Softw. 9, 6442) with the set-up of
bench/broadband/make_gpoint_reference.py: shortwave optical depth tau_abs + tau_R and
single-scattering albedo tau_R / (tau_abs + tau_R) (capped at 1 - 1e-8) per layer, Rayleigh phase
function 3/4 (1 + cos^2 Theta) (normalised Legendre moments 1, 0, 0.1), a beam of flux F_g
(normal to the beam) at mu0, a Lambert surface; longwave without scattering, Planck radiance
linear in optical depth inside each layer, layers thinner than 1e-10 given 1e-10, a Lambert
surface of emissivity 0.98, nothing from above.

PythonicDISORT gives the intensity at its Gauss quadrature angles only; its polynomial
interpolation in mu to other angles is not accurate enough for a reference (in the shortwave it
misses the values below by up to 3 per cent in the broadband sums; the script prints the
difference). The radiances at the requested angles are therefore obtained as DISORT itself
obtains its "user-angle" intensities (Stamnes et al. 1988, Appl. Opt. 27, 2502), by integrating
the source function along the line of sight:
    J(t, Omega) = ssa/(4 pi) [ sum_quadrature P(Omega . Omega') I(t, Omega') dOmega'
                               + F_g P(Omega . Omega0) exp(-t / mu0) ]
with I(t, Omega') PythonicDISORT's diffuse intensity at its quadrature angles mu_j (Gauss
weights w_j) and
    I_top(mu > 0) = I_surface(mu) exp(-tau*/mu) + int_0^tau* J(t) exp(-t/mu) dt/mu,
    I_surface(mu < 0) = int_0^tau* J(t) exp(-(tau* - t)/|mu|) dt/|mu|,
    I_surface(mu > 0) = albedo/pi (F_diffuse_down(tau*) + mu0 F_g exp(-tau*/mu0)),
the t-integral by Gauss-Legendre quadrature on sub-intervals graded geometrically towards both
ends of each layer (where the grazing quadrature streams vary fastest). The diffuse term is
summed per azimuthal Fourier mode, exactly for the solver's quadrature: with
I = sum_m I_m(t, mu_j) cos(m phi) (the modes from 2 M equidistant azimuths, M the solver's
number of modes) and the addition theorem of the associated Legendre functions
Lam_l^m = sqrt((l - m)!/(l + m)!) P_l^m,
    sum P I dOmega' = 2 pi sum_m cos(m phi) sum_(l >= m) (2l + 1) chi_l Lam_l^m(mu)
                      sum_j w_j Lam_l^m(mu_j) I_m(t, mu_j).
(PythonicDISORT treats layers of ssa below 2e-8 as non-scattering; the line integral keeps their
single scattering, less than 1e-10 W m-2 sr-1 in all.) Longwave (no scattering)
J is the Planck source itself and the same line integral is done in closed form per layer; the
surface sends eps B_sfc + (1 - eps) F_down(tau*)/pi upwards, F_down from PythonicDISORT.
Evaluated at PythonicDISORT's own quadrature angles, this reproduces its intensities (the
discrete-ordinates solution satisfies exactly this transfer equation); the script checks that.

Cloudy column (case us1976_cloud, the column of make_cloudy_reference.py): a gray cloud in layer
3 (2-3 km), the same at every g-point: shortwave optical depth tau_c = 10, single-scattering
albedo ssa_c = 0.999, Henyey-Greenstein g = 0.85; longwave 10, 0.4, 0.85. Every layer mixes its
components as kumo does: optical depth tau_abs + tau_R + tau_c, scattering optical depth
tau_R + ssa_c tau_c, phase function the scattering-weighted mean (tau_R P_R + ssa_c tau_c P_HG) /
(tau_R + ssa_c tau_c) (moments: the same mean of 1, 0, 0.1 and g^l), emission (1 - ssa) times the
Planck source. PythonicDISORT solves it with delta-M, as make_cloudy_reference.py does: N streams,
NLeg = N, f = chi_N, i.e. in the scaled optical depth t' = (1 - ssa f) t with
ssa' = (1 - f) ssa / (1 - ssa f) and chi'_l = (chi_l - f) / (1 - f), l < N (shortwave with all
N Fourier modes). The line integral runs in t' with
    J(t', Omega) = ssa'/(4 pi) sum_quadrature P'(Omega . Omega') I(t', Omega') dOmega'
                   + ssa / (1 - ssa f) F_g P(Omega . Omega0) exp(-t' / mu0) / (4 pi),
the diffuse field scattered with the solver's truncated phase function P' (the source its
solution satisfies) and the single scattering of its beam with the EXACT phase function P (the
Rayleigh and Henyey-Greenstein functions themselves, weighted as above, not a moment series):
DISORT's user-angle intensity with the TMS correction of Nakajima and Tanaka (1988, J. Quant.
Spectrosc. Radiat. Transfer 40, 51). Their IMS correction (second-order scattering near the
beam's direction, downward only) is left out: under the cloud (tau_c / mu0 = 20) it is about
1e-9 of the radiances (PythonicDISORT's own value, printed). Longwave (no beam, azimuthal mean
only): the emission (1 - ssa') B per unit t' in closed form per layer as above, the scattering
source of the cloud layer by the t'-quadrature. Scattering angles of the shortwave directions
(mu0 = 0.5): top mu = 1: 120 degrees; 0.5: 60, 104.5, 180; 0.2: 41.5, 161.5; surface mu = -1:
60; -0.5: 75.5, 120; -0.2: 18.5, 138.5. Only the last but one looks into the cloud's forward
peak, through optical depth 10 where the beam is exp(-20) of its value.

Conventions (kumo's): a direction is the direction in which light travels; mu is its cosine from
the upward vertical (mu > 0 travels up: what a downward-looking sensor at the top sees); the
relative azimuth is the azimuth of the travel direction minus the azimuth towards which the
sun's beam travels. The beam travels along Omega0 = (sqrt(1 - mu0^2), 0, -mu0), so
    cos Theta = Omega . Omega0 = -mu mu0 + sqrt(1 - mu^2) sqrt(1 - mu0^2) cos(phi).
PythonicDISORT uses the same convention (positive mu upward, beam at (-mu0, phi0), phi the
azimuth of travel); checked below.

Written, for both columns: broadband (sum over g-points) diffuse radiances in W m-2 sr-1,
shortwave at the top (mu = 1; 0.5 at relative azimuths 0, 90, 180 degrees; 0.2 at 0, 180) and
at the surface (mu = -1; -0.5 at 90, 180; -0.2 at 0, 180), longwave at the top (mu = 1, 0.5,
0.2) and at the surface (mu = -1, -0.5, -0.2); each with the absolute difference to the same
computation with half the streams (shortwave 32 and 16, longwave 64 and 32) as its accuracy
estimate. The cloudy case is also computed with twice the streams (shortwave 64, longwave 128)
to check that estimate (check 12).

Checks (printed; the script exits with status 1 and writes nothing if one fails). Differences of
a g-point are relative to F_g mu0 / pi (the radiance of a white Lambert surface under it) where
marked "scale", fluxes relative to the file's flux or, below 1e-4 of the g-point's incoming flux
(F_g mu0, longwave pi B_sfc), to that floor.
1. Convention, thin Henyey-Greenstein layer (g = 0.7, tau = 0.01, black surface, 32 moments):
   at each mu the radiance grows with cos Theta (ssa 1 - 1e-8; top mu = 0.5 at 0/90/180 and 0.2
   at 0/180, bottom mu = -0.5 at 0/90/180 and -0.2 at 0/180), and with ssa = 1e-3 it equals the
   single-scattering radiance ssa F P(Theta) / (4 pi) times the path factor to 1e-3.
2. Convention, thin Rayleigh layer: at the top, mu = 0.5, the backscatter radiance
   (cos Theta = -1, relative azimuth 180) exceeds the one at cos Theta = 0 (relative azimuth
   acos(1/3) = 70.5 degrees) by the phase-function ratio 2 to within 2 per cent.
3. The line integral at the quadrature angles equals PythonicDISORT's intensity there (every
   g-point, both stream numbers; shortwave top and surface at relative azimuths 0, 90, 180):
   shortwave to 1e-8 (scale), except in g-points with layers of ssa > 1 - 1e-6, where
   PythonicDISORT's intensities carry its round-off near ssa = 1 (up to 5e-5; tolerance 1e-3;
   see 6); longwave to 1e-6 of the g-point's largest intensity (PythonicDISORT's round-off with
   steep linear sources and its 1e-10 floor on layer optical depths).
4. Fluxes: the azimuthal mean (6 azimuths) of the upward radiance at the top integrated over the
   hemisphere with a 64-point Gauss rule in mu (not PythonicDISORT's nodes) reproduces, per
   g-point, flux_up at the top of sw_gpoint_reference.txt to 5e-4 (the file's 32-stream fluxes
   of strongly absorbing g-points are themselves uncertain at 2e-4: PythonicDISORT moves them by
   that much at 64 streams) and PythonicDISORT's 64-stream flux to 1e-4; longwave, flux_up at the
   top and flux_down at the surface of lw_gpoint_reference.txt to 1e-4.
5. The t-quadrature is converged: a finer grid (first sub-interval 2e-4, 16 nodes) changes no
   broadband radiance by more than 1e-9 relative.
6. Capping the single-scattering albedo at 1 - 1e-7 or 1 - 1e-9 instead of 1 - 1e-8 changes no
   broadband radiance by more than 1e-6 relative.
Cloudy column:
7. sw_cloudy_reference.txt and lw_cloudy_reference.txt hold the column of the g-point files
   (k-distribution, gases, set-up, levels and layers identical).
8. As 3, with the solver's truncated phase function for the beam too (the source its solution
   satisfies), at 32, 16 and 64 streams (shortwave) and 64, 32 and 128 (longwave); at twice the
   streams the tolerances are ten times larger, as PythonicDISORT's round-off grows with them
   (64 streams: 2.4e-8 (scale) in g-point 103, whose layers reach ssa = 1 - 1e-4, the same with
   a finer t-grid; 128 longwave streams: 9.9e-7 at the grazing node mu = 3.5e-4 at the top, as
   much as in the clear column).
9. Shortwave: the exact minus the truncated single scattering of the beam along the line of
   sight equals PythonicDISORT's own TMS correction at the requested angles at the top
   (subroutines.interpolate with NT_cor "eval" minus "off") to 1e-10 (scale).
10. Fluxes: the upward radiance at the top (azimuthal mean from the m = 0 terms, exact single
   scattering) integrated with the 64-point Gauss rule reproduces PythonicDISORT's flux per
   g-point to 5e-4 and the broadband flux_up at the top of sw_cloudy_reference.txt to 1e-4;
   longwave, flux_up at the top and flux_down at the surface per g-point and of
   lw_cloudy_reference.txt to 1e-4.
11. A finer t-grid (as 5) changes the shortwave radiances of every 7th g-point by less than 1e-9
   (scale) and the longwave broadband radiances by less than 1e-9 relative.
12. With twice the streams (64 shortwave, 128 longwave) no broadband radiance moves by more than
   its written accuracy estimate (the difference to half the streams).
The script also prints how far PythonicDISORT's own interpolation in mu is from the result.

Usage (about half an hour, 22 minutes of it for the cloudy shortwave at 64 streams; numpy and
PythonicDISORT 1.8):
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy "PythonicDISORT==1.8"
    /tmp/venv/bin/python bench/broadband/make_radiance_reference.py [output file]
"""

import os
import sys
import time
import warnings
from importlib import metadata

import numpy as np
from numpy.polynomial import legendre
from PythonicDISORT import pydisort, subroutines

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "..", "tests", "data", "broadband")
CASE = "us1976"
SSA_MAX = 1.0 - 1.0e-8
TAU_MIN = 1.0e-10
RAYLEIGH_CHI = np.array([1.0, 0.0, 0.1])
NQUAD_SW, NQUAD_SW_CHECK = 32, 16
NQUAD_LW, NQUAD_LW_CHECK = 64, 32
N_FLUX_CHECK = 64            # Gauss nodes in mu for the flux check
FLUX_TOL = 1.0e-4
FLUX_TOL_FILE = 5.0e-4       # the file's 32-stream fluxes carry up to 2.5e-4 themselves
NQUAD_FLUX_FINE = 64
FLUX_FLOOR = 1.0e-4          # relative to the g-point's incoming flux (F_g mu0, pi B_sfc)
NODE_TOL = 1.0e-8            # relative to F_g mu0 / pi
NODE_TOL_CONSERVATIVE = 1.0e-3
NODE_TOL_LW = 1.0e-6         # relative to the g-point's largest intensity
NODE_TOL_DOUBLE = 10.0       # factor on the node tolerances at twice the streams (round-off)
GRID_TOL = 1.0e-9
CAP_CHECK = (1.0e-7, 1.0e-9)
CAP_TOL = 1.0e-6
CLOUD_CASE = "us1976_cloud"
NQUAD_SW_DOUBLE, NQUAD_LW_DOUBLE = 64, 128
NLEG_EXACT = 300             # moments of the exact phase functions (0.85^300 < 1e-21)
TMS_TOL = 1.0e-10            # relative to F_g mu0 / pi
GRID_STRIDE = 7              # g-points of the shortwave cloudy t-quadrature check
ERROR_FLAG = 3.0e-3          # relative error above which a cloudy radiance is flagged
# (level name, mu, relative azimuth in degrees)
SW_DIRS = [("top", 1.0, 0.0), ("top", 0.5, 0.0), ("top", 0.5, 90.0), ("top", 0.5, 180.0),
           ("top", 0.2, 0.0), ("top", 0.2, 180.0),
           ("surface", -1.0, 0.0), ("surface", -0.5, 90.0), ("surface", -0.5, 180.0),
           ("surface", -0.2, 0.0), ("surface", -0.2, 180.0)]
LW_DIRS = [("top", 1.0), ("top", 0.5), ("top", 0.2),
           ("surface", -1.0), ("surface", -0.5), ("surface", -0.2)]

failures = []


def check(name, ok, detail):
    print(f"  [{'ok' if ok else 'FAILED'}] {name}: {detail}", flush=True)
    if not ok:
        failures.append(name)


def read_case(path, name):
    """Blocks of one case of a g-point reference file: {keyword: {index: values}}, and the raw
    words of its case and setup lines."""
    blocks, on = {}, False
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w or w[0].startswith("#"):
                continue
            if w[0] == "case":
                on = w[1] == name
                if on:
                    blocks["case"] = w[1:]
                continue
            if not on:
                continue
            if w[0] == "end":
                return blocks
            if w[0] in ("gases", "setup"):
                blocks[w[0]] = w[1:]
                continue
            blocks.setdefault(w[0], {})[int(w[1])] = np.array(w[2:], dtype=float)
    raise ValueError(f"case {name} not found in {path}")


def per_layer(blocks, key, nz):
    """(nz, n_gpt) array of a per-layer block, layers 1..nz from the bottom."""
    return np.array([blocks[key][k] for k in range(1, nz + 1)])


def cos_theta(mu, phi_deg, mu0):
    """Cosine of the scattering angle between the travel direction (mu, phi) and the beam's
    travel direction (-mu0, 0)."""
    return -mu * mu0 + np.sqrt(1 - mu * mu) * np.sqrt(1 - mu0 * mu0) * np.cos(np.radians(phi_deg))


def t_grid(tau_lower, h0, npt):
    """Composite Gauss-Legendre nodes and weights in optical depth over every layer (top to
    bottom), sub-intervals growing geometrically from h0 at both ends of a layer; also the layer
    index of every node."""
    x, w = legendre.leggauss(npt)
    nodes, weights, layer = [], [], []
    tops = np.concatenate([[0.0], tau_lower[:-1]])
    for l, (a, b) in enumerate(zip(tops, tau_lower)):
        d = b - a
        if d <= 4 * h0:
            edges = np.array([0.0, d])
        else:
            half = [0.0]
            h = h0
            while half[-1] + h < 0.5 * d:
                half.append(half[-1] + h)
                h *= 2
            half = np.array(half + [0.5 * d])
            edges = np.concatenate([half, d - half[-2::-1]])
        lo, hi = a + edges[:-1], a + edges[1:]
        nodes.append(((hi - lo)[:, None] * (x + 1) / 2 + lo[:, None]).ravel())
        weights.append(((hi - lo)[:, None] * w / 2).ravel())
        layer.append(np.full(nodes[-1].size, l))
    return np.concatenate(nodes), np.concatenate(weights), np.concatenate(layer)


def hg_phase(g, ct):
    """Henyey-Greenstein phase function (normalised like the Rayleigh one: mean 1 over the
    sphere)."""
    return (1 - g * g) / (1 + g * g - 2 * g * ct) ** 1.5


def rayleigh_phase(ct):
    return 0.75 * (1 + ct * ct)


def legendre_values(n, x):
    """P_l(x) for l = 0..n-1, shape (n, len(x))."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    p = np.zeros((n, x.size))
    p[0] = 1.0
    if n > 1:
        p[1] = x
    for l in range(2, n):
        p[l] = ((2 * l - 1) * x * p[l - 1] - (l - 1) * p[l - 2]) / l
    return p


def assoc_legendre(lmax, mmax, x):
    """Lam[l, m, i] = sqrt((l - m)! / (l + m)!) P_l^m(x_i) for m <= min(l, mmax), l <= lmax (0
    for m > l), without the Condon-Shortley phase, so that (addition theorem)
    P_l(cos Theta) = sum_m (2 - delta_m0) Lam_l^m(mu) Lam_l^m(mu') cos m(phi - phi')."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    s = np.sqrt(np.maximum(0.0, 1 - x * x))
    lam = np.zeros((lmax + 1, mmax + 1, x.size))
    diag = np.ones(x.size)
    for m in range(mmax + 1):
        if m > 0:
            diag = diag * s * np.sqrt((2 * m - 1) / (2 * m))
        lam[m, m] = diag
        if m < lmax:
            lam[m + 1, m] = np.sqrt(2 * m + 1) * x * diag
        for l in range(m + 2, lmax + 1):
            lam[l, m] = ((2 * l - 1) * x * lam[l - 1, m]
                         - np.sqrt((l - 1) ** 2 - m * m) * lam[l - 2, m]) / np.sqrt(l * l - m * m)
    return lam


def delta_m(ssa, chi, nquad):
    """PythonicDISORT's delta-M scaling with NLeg = nquad and f = chi_nquad (f = 0 for phase
    functions of at most nquad moments): f, the optical-depth factor 1 - ssa f, the scaled
    single-scattering albedo and the scaled moments 0..nquad-1 of every layer."""
    f = chi[:, nquad] if chi.shape[1] > nquad else np.zeros(len(chi))
    scale = 1 - ssa * f
    ssa_s = (1 - f) * ssa / scale
    chi_s = np.zeros((len(chi), nquad))
    n = min(nquad, chi.shape[1])
    chi_s[:, :n] = (chi[:, :n] - f[:, None]) / (1 - f)[:, None]
    return f, scale, ssa_s, chi_s


def intensity_modes(u, t, nquad, nmodes):
    """Azimuthal Fourier modes I_m(mu_j, t), I = sum_m I_m cos(m phi), m < nmodes, of
    PythonicDISORT's diffuse intensity at its quadrature angles, from 2 nmodes equidistant
    azimuths (exact for its nmodes modes); shape (nquad, len(t), nmodes)."""
    nphi = 2 * nmodes
    phi = 2 * np.pi * np.arange(nphi) / nphi
    modes = np.zeros((nquad, len(t), nmodes))
    chunk = max(1, int(2.0e7 / (nmodes * nquad * nquad)))      # bounds PythonicDISORT's memory
    for a in range(0, len(t), chunk):
        tc = t[a:a + chunk]
        c = np.fft.rfft(np.asarray(u(tc, phi)).reshape(nquad, len(tc), nphi), axis=-1).real
        c[..., 1:] *= 2
        modes[:, a:a + chunk] = c[..., :nmodes] / nphi
    return modes


def diffuse_source(u, t, lay, ssa_s, chi_s, nquad, nmodes, mu, cos_m):
    """Scattering source of the diffuse field, ssa/(4 pi) int P(Omega . Omega') I(t, Omega')
    dOmega' with the solver's (scaled) ssa_s and moments chi_s of the node's layer lay, for the
    directions of cosines mu and azimuthal factors cos_m[m, direction] (cos(m phi), or 1, 0, 0,
    ... for an azimuthal mean); per Fourier mode: ssa/2 sum_(l, m) (2l + 1) chi_l Lam_l^m(mu)
    cos(m phi) sum_j w_j Lam_l^m(mu_j) I_m(t, mu_j). Shape (len(mu), len(t))."""
    x, w = subroutines.Gauss_Legendre_quad(nquad // 2)
    lam_q = assoc_legendre(nquad - 1, nmodes - 1, np.concatenate([x, -x])) * np.concatenate([w, w])
    lam_d = assoc_legendre(nquad - 1, nmodes - 1, mu)
    src = np.zeros((len(mu), len(t)))
    for k in np.unique(lay):
        if ssa_s[k] <= 0:
            continue
        sel = np.flatnonzero(lay == k)
        nl = int(np.flatnonzero(chi_s[k])[-1]) + 1
        nm = min(nl, nmodes)
        a = np.einsum("lmj,jtm->lmt", lam_q[:nl, :nm],
                      intensity_modes(u, t[sel], nquad, nmodes)[:, :, :nm])
        y = ((2 * np.arange(nl) + 1) * chi_s[k, :nl])[:, None, None] * lam_d[:nl, :nm] \
            * cos_m[None, :nm, :]
        src[:, sel] = 0.5 * ssa_s[k] * np.einsum("lmd,lmt->dt", y, a)
    return src


def scaled_nodes(dtau, scale, h0, npt):
    """t_grid in the optical depth of the column (for PythonicDISORT's intensity) and the same
    nodes and weights in the delta-M scaled optical depth (for the line integral)."""
    tau_lower = np.cumsum(dtau)
    tau_s_lower = np.cumsum(dtau * scale)
    t, wt, lay = t_grid(tau_lower, h0, npt)
    ts = (tau_s_lower - dtau * scale)[lay] + (t - (tau_lower - dtau)[lay]) * scale[lay]
    return t, ts, wt * scale[lay], lay, tau_s_lower[-1]


def line_integral(source, ts, wts, tau_star, mu, i_sfc_up):
    """Radiance leaving the top (mu > 0, with the surface's i_sfc_up attenuated) or reaching the
    surface (mu < 0) from the source at the nodes ts (weights wts) of a column of optical depth
    tau_star."""
    rad = np.zeros(len(mu))
    up = mu > 0
    m = np.abs(mu)
    if up.any():
        att = np.exp(-ts[None, :] / m[up, None]) / m[up, None]
        rad[up] = (source[up] * att) @ wts + i_sfc_up * np.exp(-tau_star / m[up])
    if (~up).any():
        att = np.exp(-(tau_star - ts[None, :]) / m[~up, None]) / m[~up, None]
        rad[~up] = (source[~up] * att) @ wts
    return rad


def solve_scattering(dtau, ssa, chi, mu0, flux, albedo, nquad, mu, phi_deg, mean=None,
                     parts=None, h0=None, npt=10):
    """Diffuse radiances of one scattering column (layers top to bottom) in the travel
    directions (mu, phi_deg): mu > 0 at the top, mu < 0 at the bottom; where `mean` is set, the
    azimuthal mean at that mu instead. chi: normalised Legendre moments of the phase function,
    one row for all layers or one per layer; with more than nquad moments PythonicDISORT scales
    them by delta-M (NLeg = nquad, f = chi_nquad, all nquad Fourier modes), and the single
    scattering of the beam takes the exact phase function (Nakajima-Tanaka TMS): sum of
    weight(layer) * phase(cos Theta) over `parts`, or the moments chi if parts is None.
    Returns a dict: the radiances (rad) and those with the solver's own truncated beam source
    (rad_trunc, what PythonicDISORT's intensity is at its nodes), PythonicDISORT's quadrature
    nodes (mu_q), flux functions (fp, fm) and intensity function (u), the column's optical
    depth (tau_star) and the number of optical-depth nodes (nt)."""
    dtau = np.maximum(dtau, TAU_MIN)
    nz = len(dtau)
    chi = np.atleast_2d(chi)
    chi = np.broadcast_to(chi, (nz, chi.shape[1]))
    tau_lower = np.cumsum(dtau)
    tau_star = tau_lower[-1]
    if chi.shape[1] > nquad:
        leg, nfourier, f_arr = chi, nquad, chi[:, nquad]
    else:
        leg = np.zeros((nz, nquad))
        leg[:, :chi.shape[1]] = chi
        nfourier, f_arr = int(np.nonzero(chi)[1].max()) + 1, 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(tau_lower, ssa, nquad, leg, mu0, flux, 0.0, NLeg=nquad, NFourier=nfourier,
                       f_arr=f_arr, BDRF_Fourier_modes=[albedo] if albedo > 0 else [])
    mu_q, fp, fm, u = out[0], out[1], out[2], out[-1]
    _, scale, ssa_s, chi_s = delta_m(ssa, chi, nquad)
    if h0 is None:
        h0 = 0.2 * mu_q[:nquad // 2].min()
    t, ts, wts, lay, tau_s_star = scaled_nodes(dtau, scale, h0, npt)
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    phi_deg = np.atleast_1d(np.asarray(phi_deg, dtype=float))
    mean = np.zeros(len(mu), dtype=bool) if mean is None else np.asarray(mean)
    m = np.arange(nfourier)[:, None]
    cos_m = np.where(mean[None, :], (m == 0) * 1.0, np.cos(m * np.radians(phi_deg)[None, :]))
    diffuse = diffuse_source(u, t, lay, ssa_s, chi_s, nquad, nfourier, mu, cos_m)
    # single scattering of the beam: phase functions at the directions' cos Theta, azimuthal
    # means from the moments (P_l(mu) P_l(-mu0))
    ct = cos_theta(mu, phi_deg, mu0)
    nc = chi.shape[1]
    wl = 2 * np.arange(max(nc, nquad)) + 1
    pl0 = legendre_values(max(nc, nquad), -mu0)[:, 0]
    p_trunc, p_exact = np.zeros((len(mu), nz)), np.zeros((len(mu), nz))
    for k in range(nz):
        p_trunc[~mean, k] = legendre.legval(ct[~mean], wl[:nquad] * chi_s[k])
        p_trunc[mean, k] = legendre.legval(mu[mean], wl[:nquad] * chi_s[k] * pl0[:nquad])
        p_exact[~mean, k] = (legendre.legval(ct[~mean], wl[:nc] * chi[k]) if parts is None
                             else sum(wp[k] * phase(ct[~mean]) for wp, phase in parts))
        p_exact[mean, k] = legendre.legval(mu[mean], wl[:nc] * chi[k] * pl0[:nc])
    beam = flux / (4 * np.pi) * np.exp(-ts / mu0)
    down_diffuse, _ = fm(tau_star)
    i_sfc = albedo / np.pi * (down_diffuse + mu0 * flux * np.exp(-tau_star / mu0))
    rad = line_integral(diffuse + (ssa / scale)[lay] * p_exact[:, lay] * beam, ts, wts,
                        tau_s_star, mu, i_sfc)
    rad_trunc = rad
    if chi.shape[1] > nquad or parts is not None:
        rad_trunc = line_integral(diffuse + ssa_s[lay] * p_trunc[:, lay] * beam, ts, wts,
                                  tau_s_star, mu, i_sfc)
    return dict(rad=rad, rad_trunc=rad_trunc, mu_q=mu_q, fp=fp, fm=fm, tau_star=tau_star, u=u,
                nt=len(t))


def do_flux_up_top(dtau, ssa, chi, mu0, flux, albedo, nquad):
    """PythonicDISORT's upward flux at the top (fluxes only)."""
    dtau = np.maximum(dtau, TAU_MIN)
    leg = np.zeros((len(dtau), nquad))
    leg[:, :len(chi)] = chi
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(np.cumsum(dtau), ssa, nquad, leg, mu0, flux, 0.0, only_flux=True,
                       BDRF_Fourier_modes=[albedo] if albedo > 0 else [])
    return float(out[1](0.0))


def interpolated(res, mu, phi_deg):
    """PythonicDISORT's own polynomial interpolation in mu (for comparison only)."""
    ui = subroutines.interpolate(res["u"])
    return np.array([ui(m, 0.0 if m > 0 else res["tau_star"], np.radians(p))
                     for m, p in zip(mu, phi_deg)])


def lw_line_integral(dtau, b_top, b_bot, i_sfc_up, mu):
    """Radiance without scattering, Planck source linear in optical depth within each layer
    (layers top to bottom; b_top, b_bot at each layer's top and bottom): mu > 0 upward at the
    top, starting from i_sfc_up at the surface; mu < 0 downward at the surface, nothing from
    above. Closed form per layer."""
    def g(x):   # (1 - exp(-x) (1 + x)) / x, its series for small x
        xs = np.where(x < 1e-4, 1.0, x)
        return np.where(x < 1e-4, x / 2 - x * x / 3 + x ** 3 / 8,
                        -(np.expm1(-xs) + xs * np.exp(-xs)) / xs)
    rad = np.zeros(len(mu))
    for j, mj in enumerate(mu):
        m = abs(mj)
        x = dtau / m
        tr = np.exp(-x)
        if mj > 0:
            i = i_sfc_up
            for l in range(len(dtau) - 1, -1, -1):   # bottom to top
                i = i * tr[l] - b_top[l] * np.expm1(-x[l]) + (b_bot[l] - b_top[l]) * g(x[l])
        else:
            i = 0.0
            for l in range(len(dtau)):               # top to bottom
                i = i * tr[l] - b_bot[l] * np.expm1(-x[l]) + (b_top[l] - b_bot[l]) * g(x[l])
        rad[j] = i
    return rad


def solve_lw(dtau, b_top, b_bot, b_sfc, emissivity, nquad, mu, ssa=None, chi=None, h0=None,
             npt=10):
    """Radiances of one longwave g-point (layers top to bottom) and PythonicDISORT's outputs.
    Without ssa, no scattering; with ssa and per-layer moments chi (more than nquad of them),
    scattering with delta-M (NLeg = nquad, f = chi_nquad; no beam, so only the azimuthal mean):
    the emission (1 - ssa) B of every layer in closed form, the scattering source of the diffuse
    field by quadrature in optical depth."""
    thin = dtau < TAU_MIN
    dt = np.maximum(dtau, TAU_MIN)
    tau_lower = np.cumsum(dt)
    tau_upper = tau_lower - dt
    slope = np.where(thin, 0.0, (b_bot - b_top) / dt)
    b_up = np.where(thin, 0.5 * (b_top + b_bot), b_top)
    s_poly = np.column_stack([b_up - slope * tau_upper, slope])
    if ssa is None:
        ssa = np.zeros(len(dt))
        chi = np.zeros((len(dt), nquad))
        chi[:, 0] = 1.0
        f_arr = 0.0
    else:
        f_arr = chi[:, nquad]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(tau_lower, ssa, nquad, chi, 0.5, 0.0, 0.0, NLeg=nquad, NFourier=1,
                       f_arr=f_arr, b_pos=emissivity * b_sfc, b_neg=0.0,
                       BDRF_Fourier_modes=[1.0 - emissivity], s_poly_coeffs=s_poly)
    mu_q, fp, fm, u = out[0], out[1], out[2], out[-1]
    down_sfc, _ = fm(tau_lower[-1])
    i_sfc = emissivity * b_sfc + (1 - emissivity) * down_sfc / np.pi
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    _, scale, ssa_s, chi_s = delta_m(ssa, chi, nquad)
    rad = lw_line_integral(dtau * scale, (1 - ssa_s) * b_top, (1 - ssa_s) * b_bot, i_sfc, mu)
    if np.any(ssa > 0):
        if h0 is None:
            h0 = 0.2 * mu_q[:nquad // 2].min()
        t, ts, wts, lay, tau_s_star = scaled_nodes(dt, scale, h0, npt)
        on = ssa[lay] > 0
        src = diffuse_source(u, t[on], lay[on], ssa_s, chi_s, nquad, 1, mu, np.ones((1, len(mu))))
        rad += line_integral(src, ts[on], wts[on], tau_s_star, mu, 0.0)
    return dict(rad=rad, mu_q=mu_q, fp=fp, fm=fm, tau_star=tau_lower[-1], u=u,
                i_sfc=i_sfc)


def convention_checks():
    """Checks 1 and 2 (see the header)."""
    print("convention checks (thin layer tau = 0.01, black surface, mu0 = 0.5, F = 1):")
    mu0, tau, g = 0.5, 0.01, 0.7
    chi_hg = g ** np.arange(NQUAD_SW)
    dirs = [(0.5, 0.0), (0.5, 90.0), (0.5, 180.0), (0.2, 0.0), (0.2, 180.0),
            (-0.5, 90.0), (-0.5, 180.0), (-0.2, 0.0), (-0.2, 180.0), (-0.5, 0.0)]
    mu = np.array([d[0] for d in dirs])
    ph = np.array([d[1] for d in dirs])
    ct = cos_theta(mu, ph, mu0)
    r = solve_scattering(np.array([tau]), np.array([SSA_MAX]), chi_hg, mu0, 1.0, 0.0,
                         NQUAD_SW, mu, ph)["rad"]
    lines = []
    ok = True
    for m in np.unique(mu):
        sel = np.nonzero(mu == m)[0]
        by_ct = sel[np.argsort(ct[sel])]
        ok &= bool(np.all(np.diff(r[by_ct]) > 0))
        lines.append(f"mu {m:+.1f}: " + ", ".join(
            f"phi {ph[k]:.0f} cosT {ct[k]:+.3f} I {r[k]:.4e}" for k in by_ct))
    check("HG g=0.7 radiance increases with cos Theta at each mu", ok, "; ".join(lines))
    # Single scattering (ssa 1e-3): I = ssa F P / (4 pi) * path factor, P the truncated HG.
    ssa = 1e-3
    r = solve_scattering(np.array([tau]), np.array([ssa]), chi_hg, mu0, 1.0, 0.0, NQUAD_SW,
                         mu, ph)["rad"]
    p = legendre.legval(ct, (2 * np.arange(NQUAD_SW) + 1) * chi_hg)
    m = np.abs(mu)
    path = np.where(mu > 0, mu0 / (mu0 + m) * (1 - np.exp(-tau * (1 / m + 1 / mu0))),
                    np.where(np.isclose(m, mu0), tau / m * np.exp(-tau / m),
                             mu0 / (mu0 - np.where(np.isclose(m, mu0), 0, m))
                             * (np.exp(-tau / mu0) - np.exp(-tau / m))))
    ss = ssa / (4 * np.pi) * p * path
    rel = np.max(np.abs(r / ss - 1))
    check("HG single scattering (ssa 1e-3) = ssa F P(Theta)/(4 pi) x path factor", rel < 1e-3,
          f"max relative difference {rel:.2e} over the {len(dirs)} directions")
    # Rayleigh: backscatter (cos Theta = -1) against cos Theta = 0, same mu.
    phi_90 = np.degrees(np.arccos(1.0 / 3.0))
    mu = np.array([0.5, 0.5])
    ph = np.array([180.0, phi_90])
    ct = cos_theta(mu, ph, mu0)
    r = solve_scattering(np.array([tau]), np.array([SSA_MAX]), RAYLEIGH_CHI, mu0, 1.0, 0.0,
                         NQUAD_SW, mu, ph)["rad"]
    ratio = r[0] / r[1]
    check("Rayleigh at the top, mu 0.5: I(cosT -1) > I(cosT 0), ratio ~ P(-1)/P(0) = 2",
          ratio > 1 and abs(ratio / 2 - 1) < 0.02,
          f"cosT {ct[0]:+.3f}: {r[0]:.6e}, cosT {ct[1]:+.3f}: {r[1]:.6e}, ratio {ratio:.5f}")


def run_sw():
    sw = read_case(os.path.join(DATA, "sw_gpoint_reference.txt"), CASE)
    nz, ng = int(sw["case"][2]), int(sw["case"][4])
    mu0, albedo, tsi = (float(v) for v in sw["setup"][:3])
    tau = per_layer(sw, "tau", nz)[::-1]                 # top to bottom
    ray = per_layer(sw, "tau_rayleigh", nz)[::-1]
    solar = sw["solar_flux"][0]
    flux_up_top = sw["flux_up"][nz]
    print(f"shortwave: case {CASE}, {nz} layers, {ng} g-points, mu0 {mu0}, albedo {albedo}, "
          f"TSI {tsi} (sum of solar_flux {solar.sum():.6f})")
    dtau = tau + ray
    ssa_raw = ray / dtau
    # g-points with layers (nearly) without absorption, where PythonicDISORT's intensities carry
    # its round-off near ssa = 1
    conservative = ssa_raw.max(axis=0) > 1 - 1e-6
    scale = solar * mu0 / np.pi        # radiance of a white Lambert surface under the g-point
    mu = np.array([d[1] for d in SW_DIRS])
    ph = np.array([d[2] for d in SW_DIRS])
    nd = len(mu)
    # flux check directions: 64 Gauss nodes in (0, 1) x 6 azimuths (exact for modes 0..2)
    x_f, w_f = subroutines.Gauss_Legendre_quad(N_FLUX_CHECK)
    mu_f = np.repeat(x_f, 6)
    ph_f = np.tile(np.arange(6) * 60.0, N_FLUX_CHECK)
    nf = len(mu_f)
    phi_node = np.array([0.0, 90.0, 180.0])
    rad = {}
    node_err = np.zeros((2, ng))
    flux_rel = np.zeros((ng, 2))
    flux_int = np.zeros(ng)
    flux_fine = np.zeros(ng)
    interp = np.zeros((ng, nd))
    for nq in (NQUAD_SW, NQUAD_SW_CHECK):
        n = nq // 2
        mu_nodes = subroutines.Gauss_Legendre_quad(n)[0]
        mu_n = np.concatenate([np.repeat(mu_nodes, 3), np.repeat(-mu_nodes, 3)])
        ph_n = np.tile(phi_node, 2 * n)
        rad[nq] = np.zeros((ng, nd))
        for g in range(ng):
            ssa = np.minimum(ssa_raw[:, g], SSA_MAX)
            res = solve_scattering(dtau[:, g], ssa, RAYLEIGH_CHI, mu0, solar[g], albedo, nq,
                                   np.concatenate([mu, mu_f, mu_n]),
                                   np.concatenate([ph, ph_f, ph_n]))
            r = res["rad"]
            rad[nq][g] = r[:nd]
            # check 3: at the quadrature nodes, PythonicDISORT's own intensity
            u_top = np.asarray(res["u"](0.0, np.radians(phi_node)))[:n]
            u_bot = np.asarray(res["u"](res["tau_star"], np.radians(phi_node)))[n:]
            ref = np.concatenate([u_top, u_bot]).ravel()
            node_err[0 if nq == NQUAD_SW else 1, g] = np.max(np.abs(r[nd + nf:] - ref)) / scale[g]
            if nq == NQUAD_SW:
                # check 4: hemispheric integral of the azimuthal mean at the top
                r_f = r[nd:nd + nf].reshape(N_FLUX_CHECK, 6).mean(axis=1)
                f_int = flux_int[g] = 2 * np.pi * np.sum(w_f * x_f * r_f)
                flux_fine[g] = do_flux_up_top(dtau[:, g], ssa, RAYLEIGH_CHI, mu0, solar[g], albedo,
                                           NQUAD_FLUX_FINE)
                floor = FLUX_FLOOR * solar[g] * mu0
                flux_rel[g] = (abs(f_int - flux_up_top[g]) / max(flux_up_top[g], floor),
                               abs(f_int - flux_fine[g]) / max(flux_fine[g], floor))
                interp[g] = interpolated(res, mu, ph)
    bb = rad[NQUAD_SW].sum(0)
    bbc = rad[NQUAD_SW_CHECK].sum(0)
    e_plain = node_err[:, ~conservative].max()
    e_cons = node_err[:, conservative].max()
    check("shortwave line integral at the quadrature angles = PythonicDISORT's intensity",
          e_plain < NODE_TOL and e_cons < NODE_TOL_CONSERVATIVE,
          f"max difference / (F_g mu0 / pi): {e_plain:.2e} in the {np.sum(~conservative)} "
          f"g-points whose layers all have ssa < 1 - 1e-6; {e_cons:.2e} in the "
          f"{np.sum(conservative)} others (PythonicDISORT's round-off near ssa = 1, see check 6)")
    above = flux_up_top >= FLUX_FLOOR * solar * mu0
    check("shortwave TOA flux_up from the radiances = sw_gpoint_reference.txt per g-point",
          flux_rel[:, 0].max() < FLUX_TOL_FILE,
          f"max relative difference {flux_rel[above, 0].max():.2e} (g-point "
          f"{np.flatnonzero(above)[np.argmax(flux_rel[above, 0])] + 1}) over the {above.sum()} "
          f"g-points reflecting more than {FLUX_FLOOR:g} of their incoming flux, "
          f"{flux_rel[~above, 0].max():.2e} of {FLUX_FLOOR:g} F_g mu0 for the other "
          f"{np.sum(~above)}; broadband {flux_int.sum():.6f} W m-2, file "
          f"{flux_up_top.sum():.6f}")
    file_move = np.max(np.abs(flux_fine - flux_up_top)
                       / np.maximum(flux_fine, FLUX_FLOOR * solar * mu0))
    check(f"shortwave TOA flux_up from the radiances = PythonicDISORT's flux with "
          f"{NQUAD_FLUX_FINE} streams", flux_rel[:, 1].max() < FLUX_TOL,
          f"max relative difference {flux_rel[above, 1].max():.2e} (g-point "
          f"{np.flatnonzero(above)[np.argmax(flux_rel[above, 1])] + 1}), "
          f"{flux_rel[~above, 1].max():.2e} below the floor; broadband {flux_fine.sum():.6f} W m-2"
          f" (the file's {NQUAD_SW}-stream fluxes move by up to {file_move:.1e} at "
          f"{NQUAD_FLUX_FINE} streams)")
    # check 5: finer t-quadrature; check 6: other caps of the single-scattering albedo
    fine = np.zeros((ng, nd))
    capped = {cap: np.zeros((ng, nd)) for cap in CAP_CHECK}
    for g in range(ng):
        ssa = np.minimum(ssa_raw[:, g], SSA_MAX)
        fine[g] = solve_scattering(dtau[:, g], ssa, RAYLEIGH_CHI, mu0, solar[g], albedo,
                                   NQUAD_SW, mu, ph, h0=2e-4, npt=16)["rad"]
        for cap in CAP_CHECK:
            if conservative[g]:
                capped[cap][g] = solve_scattering(
                    dtau[:, g], np.minimum(ssa_raw[:, g], 1 - cap), RAYLEIGH_CHI, mu0, solar[g],
                    albedo, NQUAD_SW, mu, ph)["rad"]
            else:
                capped[cap][g] = rad[NQUAD_SW][g]
    grid = np.max(np.abs(fine.sum(0) / bb - 1))
    grid_g = np.max(np.abs(fine - rad[NQUAD_SW]) / scale[:, None])
    check("shortwave t-quadrature converged (finer grid)", grid < GRID_TOL,
          f"broadband max relative change {grid:.2e}; per g-point {grid_g:.2e} of F_g mu0 / pi")
    cap_bb = max(np.max(np.abs(c.sum(0) / bb - 1)) for c in capped.values())
    cap_g = max(np.max(np.abs(c - rad[NQUAD_SW]) / scale[:, None]) for c in capped.values())
    check(f"shortwave ssa cap 1 - {' or 1 - '.join(f'{c:g}' for c in CAP_CHECK)} instead of "
          f"1 - 1e-8", cap_bb < CAP_TOL,
          f"broadband max relative change {cap_bb:.2e}; per g-point {cap_g:.2e} of F_g mu0 / pi")
    print(f"    (PythonicDISORT's polynomial interpolation in mu differs from the line integral "
          f"by up to {np.max(np.abs(interp.sum(0) / bb - 1)):.2e} relative in the broadband and "
          f"{np.max(np.abs(interp - rad[NQUAD_SW]) / scale[:, None]):.2e} of F_g mu0 / pi in a "
          f"single g-point: not used)")
    return dict(nz=nz, ng=ng, mu0=mu0, albedo=albedo, tsi=tsi, mu=mu, ph=ph, rad=bb,
                diff=np.abs(bb - bbc), ct=cos_theta(mu, ph, mu0))


def run_lw():
    lw = read_case(os.path.join(DATA, "lw_gpoint_reference.txt"), CASE)
    nz, ng = int(lw["case"][2]), int(lw["case"][4])
    t_sfc, emis = (float(v) for v in lw["setup"][:2])
    tau = per_layer(lw, "tau", nz)[::-1]
    b_bot = per_layer(lw, "lev_src_bot", nz)[::-1]
    b_top = per_layer(lw, "lev_src_top", nz)[::-1]
    b_sfc = lw["sfc_src"][0]
    up_top, dn_sfc = lw["flux_up"][nz], lw["flux_down"][0]
    print(f"longwave: case {CASE}, {nz} layers, {ng} g-points, surface {t_sfc} K, "
          f"emissivity {emis}")
    mu = np.array([d[1] for d in LW_DIRS])
    x_f, w_f = subroutines.Gauss_Legendre_quad(N_FLUX_CHECK)
    rad = {nq: np.zeros((ng, len(mu))) for nq in (NQUAD_LW, NQUAD_LW_CHECK)}
    interp = np.zeros((ng, len(mu)))
    flux_rel = np.zeros((ng, 2))
    flux_int = np.zeros((ng, 2))
    node_rel = 0.0
    for nq in (NQUAD_LW, NQUAD_LW_CHECK):
        n = nq // 2
        mu_nodes = subroutines.Gauss_Legendre_quad(n)[0]
        for g in range(ng):
            allmu = np.concatenate([mu, x_f, -x_f, mu_nodes, -mu_nodes])
            res = solve_lw(tau[:, g], b_top[:, g], b_bot[:, g], b_sfc[g], emis, nq, allmu)
            r = res["rad"]
            rad[nq][g] = r[:len(mu)]
            k = len(mu) + 2 * N_FLUX_CHECK
            ref = np.concatenate([np.asarray(res["u"](0.0, 0.0))[:n],
                                  np.asarray(res["u"](res["tau_star"], 0.0))[n:]])
            node_rel = max(node_rel, np.max(np.abs(r[k:] - ref)) / np.max(np.abs(ref)))
            if nq == NQUAD_LW:
                flux_int[g] = (2 * np.pi * np.sum(w_f * x_f * r[len(mu):len(mu) + N_FLUX_CHECK]),
                               2 * np.pi * np.sum(w_f * x_f * r[len(mu) + N_FLUX_CHECK:k]))
                floor = FLUX_FLOOR * np.pi * b_sfc[g]
                flux_rel[g] = (abs(flux_int[g, 0] - up_top[g]) / max(up_top[g], floor),
                               abs(flux_int[g, 1] - dn_sfc[g]) / max(dn_sfc[g], floor))
                ui = subroutines.interpolate(res["u"])
                interp[g] = [ui(m, 0.0 if m > 0 else res["tau_star"], 0.0) for m in mu]
    bb = rad[NQUAD_LW].sum(0)
    bbc = rad[NQUAD_LW_CHECK].sum(0)
    check("longwave line integral at the quadrature angles = PythonicDISORT's intensity",
          node_rel < NODE_TOL_LW, f"max difference {node_rel:.2e} of the g-point's largest "
          f"intensity (both stream numbers, all g-points; PythonicDISORT's own round-off with "
          f"steep linear sources and its 1e-10 floor on layer optical depths)")
    check("longwave TOA flux_up and surface flux_down from the radiances = "
          "lw_gpoint_reference.txt per g-point", flux_rel.max() < FLUX_TOL,
          f"max relative difference up {flux_rel[:, 0].max():.2e} (g-point "
          f"{np.argmax(flux_rel[:, 0]) + 1}), down {flux_rel[:, 1].max():.2e} (g-point "
          f"{np.argmax(flux_rel[:, 1]) + 1}); broadband up {flux_int[:, 0].sum():.6f} "
          f"(file {up_top.sum():.6f}), down {flux_int[:, 1].sum():.6f} (file "
          f"{dn_sfc.sum():.6f}) W m-2")
    print(f"    (PythonicDISORT's polynomial interpolation in mu differs from the closed form "
          f"by up to {np.max(np.abs(interp.sum(0) / bb - 1)):.2e} relative in the broadband: "
          f"not used)")
    return dict(nz=nz, ng=ng, t_sfc=t_sfc, emis=emis, mu=mu, rad=bb, diff=np.abs(bb - bbc))


def read_cloudy(band):
    """The clear column's blocks (per-g-point optics) of <band>_gpoint_reference.txt and the
    cloudy case's blocks (set-up, cloud, broadband fluxes) of <band>_cloudy_reference.txt, after
    checking that both describe the same column."""
    clear = read_case(os.path.join(DATA, f"{band}_gpoint_reference.txt"), CASE)
    cloudy = read_case(os.path.join(DATA, f"{band}_cloudy_reference.txt"), CLOUD_CASE)
    same = (clear["case"][1:4] == cloudy["case"][1:4] and clear["gases"] == cloudy["gases"]
            and clear["setup"] == cloudy["setup"]
            and all(np.array_equal(clear[key][i], cloudy[key][i])
                    for key in ("level", "layer") for i in clear[key]))
    check(f"{band}_cloudy_reference.txt holds the column {CASE} of {band}_gpoint_reference.txt",
          same, "k-distribution, gases, set-up, levels and layers identical")
    return clear, cloudy


def cloud_optics(tau_abs, tau_ray, layer, cloud):
    """Optics of every layer (top to bottom) of one g-point with the gray cloud (optical depth,
    single-scattering albedo, Henyey-Greenstein g) in `layer` (from the bottom), mixed as kumo
    mixes the components of a layer: optical depths add, scattering optical depths add (Rayleigh
    and cloud), the phase function is the scattering-weighted mean of the components' (moments
    0..NLEG_EXACT-1 and the exact functions). Returns the optical depth, the single-scattering
    albedo, the moments and the components [(weight of every layer, phase function)]."""
    nz = len(tau_abs)
    c_tau, c_ssa, c_g = cloud
    tau_c = np.zeros(nz)
    tau_c[nz - layer] = c_tau
    sca_c = tau_c * c_ssa
    dtau = tau_abs + tau_ray + tau_c
    sca = tau_ray + sca_c
    ssa = np.divide(sca, dtau, out=np.zeros(nz), where=dtau > 0)
    w_ray = np.divide(tau_ray, sca, out=np.zeros(nz), where=sca > 0)
    w_cld = np.divide(sca_c, sca, out=np.zeros(nz), where=sca > 0)
    chi = np.zeros((nz, NLEG_EXACT))
    chi[:, :len(RAYLEIGH_CHI)] = w_ray[:, None] * RAYLEIGH_CHI
    chi += w_cld[:, None] * c_g ** np.arange(NLEG_EXACT)
    chi[sca == 0, 0] = 1.0
    return dtau, ssa, chi, [(w_ray, rayleigh_phase), (w_cld, lambda ct: hg_phase(c_g, ct))]


def stream_checks(band, bb, bbc, bbd, nq, nqc, nqd):
    """The error column |bb - bbc| against the run with twice the streams."""
    err = np.abs(bb - bbc)
    d = np.abs(bbd - bb)
    ratio = np.divide(d, err, out=np.full(len(d), np.inf), where=err > 0)
    check(f"{band} {nq} streams within the {nqc}-stream difference of {nqd} streams",
          np.all(d <= err), f"|{nqd} - {nq}| / |{nq} - {nqc}| at most {ratio.max():.3f}; "
          f"|{nqd} - {nq}| at most {np.max(d / bb):.1e} relative, |{nq} - {nqc}| at most "
          f"{np.max(err / bb):.1e}")
    return err, d


def run_sw_cloudy():
    clear, cloudy = read_cloudy("sw")
    nz, ng = int(clear["case"][2]), int(clear["case"][4])
    mu0, albedo, tsi = (float(v) for v in cloudy["setup"][:3])
    (layer, cloud), = cloudy["cloud"].items()
    cloud = tuple(float(v) for v in cloud)
    tau = per_layer(clear, "tau", nz)[::-1]
    ray = per_layer(clear, "tau_rayleigh", nz)[::-1]
    solar = clear["solar_flux"][0]
    up_file = cloudy["broadband"][nz][0]
    print(f"shortwave: case {CLOUD_CASE}, cloud in layer {layer}: optical depth {cloud[0]:g}, "
          f"ssa {cloud[1]:g}, g {cloud[2]:g}; mu0 {mu0}, albedo {albedo}")
    optics = [cloud_optics(tau[:, g], ray[:, g], layer, cloud) for g in range(ng)]
    conservative = np.array([o[1].max() for o in optics]) > 1 - 1e-6
    scale = solar * mu0 / np.pi
    mu = np.array([d[1] for d in SW_DIRS])
    ph = np.array([d[2] for d in SW_DIRS])
    nd = len(mu)
    top = mu > 0
    x_f, w_f = subroutines.Gauss_Legendre_quad(N_FLUX_CHECK)
    phi_node = np.array([0.0, 90.0, 180.0])
    streams = (NQUAD_SW, NQUAD_SW_CHECK, NQUAD_SW_DOUBLE)
    rad = {nq: np.zeros((ng, nd)) for nq in streams}
    trunc = np.zeros((ng, nd))
    node_err = np.zeros((len(streams), ng))
    flux_int, flux_pd = np.zeros(ng), np.zeros(ng)
    nt_err = np.zeros(ng)
    ims = np.zeros((ng, nd))
    pd_eval = np.zeros((ng, nd))
    for i, nq in enumerate(streams):
        t0 = time.time()
        n = nq // 2
        mu_nodes = subroutines.Gauss_Legendre_quad(n)[0]
        mu_n = np.concatenate([np.repeat(mu_nodes, 3), np.repeat(-mu_nodes, 3)])
        allmu = np.concatenate([mu, x_f, mu_n])
        allph = np.concatenate([ph, np.zeros(N_FLUX_CHECK), np.tile(phi_node, 2 * n)])
        mean = np.arange(len(allmu)) >= nd
        mean[nd + N_FLUX_CHECK:] = False
        for g in range(ng):
            dtau, ssa, chi, parts = optics[g]
            res = solve_scattering(dtau, np.minimum(ssa, SSA_MAX), chi, mu0, solar[g], albedo, nq,
                                   allmu, allph, mean=mean, parts=parts)
            rad[nq][g] = res["rad"][:nd]
            u = res["u"]
            ref = np.concatenate([np.asarray(u(0.0, np.radians(phi_node)))[:n],
                                  np.asarray(u(res["tau_star"], np.radians(phi_node)))[n:]])
            node_err[i, g] = np.max(np.abs(res["rad_trunc"][nd + N_FLUX_CHECK:]
                                           - ref.ravel())) / scale[g]
            if nq != NQUAD_SW:
                continue
            trunc[g] = res["rad_trunc"][:nd]
            flux_int[g] = 2 * np.pi * np.sum(w_f * x_f * res["rad"][nd:nd + N_FLUX_CHECK])
            flux_pd[g] = float(res["fp"](0.0))
            # PythonicDISORT's own Nakajima-Tanaka corrections at the requested angles
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with_nt = subroutines.interpolate(u, NT_cor="eval")
                without = subroutines.interpolate(u, NT_cor="off")
                for lev, sel in ((0.0, top), (res["tau_star"], ~top)):
                    a = np.diagonal(with_nt(mu[sel], lev, np.radians(ph[sel])))
                    b = np.diagonal(without(mu[sel], lev, np.radians(ph[sel])))
                    ims[g, sel] = (a - b) - (res["rad"][:nd] - res["rad_trunc"][:nd])[sel]
                    pd_eval[g, sel] = a
            nt_err[g] = np.max(np.abs(ims[g, top])) / scale[g]
        print(f"    {nq} streams: {time.time() - t0:.0f} s", flush=True)
    bb = rad[NQUAD_SW].sum(0)
    err, d_double = stream_checks("shortwave cloudy", bb, rad[NQUAD_SW_CHECK].sum(0),
                                  rad[NQUAD_SW_DOUBLE].sum(0), NQUAD_SW, NQUAD_SW_CHECK,
                                  NQUAD_SW_DOUBLE)
    e_plain = node_err[:, ~conservative].max(axis=1)
    e_cons = node_err[:, conservative].max(axis=1)
    worst = np.flatnonzero(~conservative)[np.argmax(node_err[:, ~conservative], axis=1)] + 1
    tol_factor = np.array([1.0, 1.0, NODE_TOL_DOUBLE])
    check("shortwave cloudy line integral (with the solver's truncated phase function) at the "
          "quadrature angles = PythonicDISORT's intensity",
          np.all(e_plain < NODE_TOL * tol_factor) and np.all(e_cons < NODE_TOL_CONSERVATIVE),
          "max difference / (F_g mu0 / pi) in the "
          f"{np.sum(~conservative)} g-points whose layers all have ssa < 1 - 1e-6: "
          + ", ".join(f"{e:.2e} (g-point {w}) at {q}" for e, w, q in zip(e_plain, worst, streams))
          + f" streams; in the {np.sum(conservative)} others: "
          + ", ".join(f"{e:.2e} at {q}" for e, q in zip(e_cons, streams)) + " streams")
    check("shortwave cloudy exact single scattering minus truncated = PythonicDISORT's TMS "
          "correction at the top", nt_err.max() < TMS_TOL,
          f"max difference {nt_err.max():.1e} of F_g mu0 / pi; exact single scattering changes "
          f"the broadband radiances by {np.max(np.abs(bb / trunc.sum(0) - 1)):.1e} relative; "
          f"PythonicDISORT's IMS correction at the surface (not applied) "
          f"{np.max(np.abs(ims.sum(0)[~top] / bb[~top])):.1e} relative")
    floor = FLUX_FLOOR * solar * mu0
    rel = np.abs(flux_int - flux_pd) / np.maximum(flux_pd, floor)
    rel_file = abs(flux_int.sum() / up_file - 1)
    check("shortwave cloudy TOA flux_up from the radiances = PythonicDISORT's flux per g-point "
          "and sw_cloudy_reference.txt", rel.max() < FLUX_TOL_FILE and rel_file < FLUX_TOL,
          f"per g-point max relative difference {rel.max():.2e} (g-point {np.argmax(rel) + 1}); "
          f"broadband {flux_int.sum():.6f} W m-2, PythonicDISORT {flux_pd.sum():.6f}, file "
          f"{up_file:.6f} (relative difference {rel_file:.1e})")
    sub = np.arange(0, ng, GRID_STRIDE)
    fine = np.array([solve_scattering(optics[g][0], np.minimum(optics[g][1], SSA_MAX),
                                      optics[g][2], mu0, solar[g], albedo, NQUAD_SW, mu, ph,
                                      parts=optics[g][3], h0=2e-4, npt=16)["rad"] for g in sub])
    grid_g = np.max(np.abs(fine - rad[NQUAD_SW][sub]) / scale[sub, None])
    check("shortwave cloudy t-quadrature converged (finer grid)", grid_g < GRID_TOL,
          f"g-points 1, 1 + {GRID_STRIDE}, ..., {sub[-1] + 1}: max change {grid_g:.2e} of "
          f"F_g mu0 / pi")
    print(f"    (PythonicDISORT's polynomial interpolation in mu with the corrections at the "
          f"requested angles differs from the line integral by up to "
          f"{np.max(np.abs(pd_eval.sum(0) / bb - 1)):.2e} relative in the broadband: not used)")
    return dict(nz=nz, ng=ng, mu0=mu0, albedo=albedo, tsi=tsi, layer=layer, cloud=cloud, mu=mu,
                ph=ph, rad=bb, diff=err, double=d_double, ct=cos_theta(mu, ph, mu0),
                tms=bb / trunc.sum(0) - 1)


def run_lw_cloudy():
    clear, cloudy = read_cloudy("lw")
    nz, ng = int(clear["case"][2]), int(clear["case"][4])
    t_sfc, emis = (float(v) for v in cloudy["setup"][:2])
    (layer, cloud), = cloudy["cloud"].items()
    cloud = tuple(float(v) for v in cloud)
    tau = per_layer(clear, "tau", nz)[::-1]
    b_bot = per_layer(clear, "lev_src_bot", nz)[::-1]
    b_top = per_layer(clear, "lev_src_top", nz)[::-1]
    b_sfc = clear["sfc_src"][0]
    up_file, dn_file = cloudy["broadband"][nz][0], cloudy["broadband"][0][1]
    print(f"longwave: case {CLOUD_CASE}, cloud in layer {layer}: optical depth {cloud[0]:g}, "
          f"ssa {cloud[1]:g}, g {cloud[2]:g}; surface {t_sfc} K, emissivity {emis}")
    optics = [cloud_optics(tau[:, g], np.zeros(nz), layer, cloud)[:3] for g in range(ng)]
    mu = np.array([d[1] for d in LW_DIRS])
    nd = len(mu)
    x_f, w_f = subroutines.Gauss_Legendre_quad(N_FLUX_CHECK)
    streams = (NQUAD_LW, NQUAD_LW_CHECK, NQUAD_LW_DOUBLE)
    rad = {nq: np.zeros((ng, nd)) for nq in streams}
    flux_int, flux_pd = np.zeros((ng, 2)), np.zeros((ng, 2))
    node_rel = np.zeros(len(streams))
    for i, nq in enumerate(streams):
        t0 = time.time()
        n = nq // 2
        mu_nodes = subroutines.Gauss_Legendre_quad(n)[0]
        allmu = np.concatenate([mu, x_f, -x_f, mu_nodes, -mu_nodes])
        k = nd + 2 * N_FLUX_CHECK
        for g in range(ng):
            dtau, ssa, chi = optics[g]
            res = solve_lw(dtau, b_top[:, g], b_bot[:, g], b_sfc[g], emis, nq, allmu, ssa=ssa,
                           chi=chi)
            r = res["rad"]
            rad[nq][g] = r[:nd]
            ref = np.concatenate([np.asarray(res["u"](0.0, 0.0))[:n],
                                  np.asarray(res["u"](res["tau_star"], 0.0))[n:]])
            node_rel[i] = max(node_rel[i], np.max(np.abs(r[k:] - ref)) / np.max(np.abs(ref)))
            if nq == NQUAD_LW:
                flux_int[g] = (2 * np.pi * np.sum(w_f * x_f * r[nd:nd + N_FLUX_CHECK]),
                               2 * np.pi * np.sum(w_f * x_f * r[nd + N_FLUX_CHECK:k]))
                flux_pd[g] = (float(res["fp"](0.0)), float(res["fm"](res["tau_star"])[0]))
        print(f"    {nq} streams: {time.time() - t0:.0f} s", flush=True)
    bb = rad[NQUAD_LW].sum(0)
    err, d_double = stream_checks("longwave cloudy", bb, rad[NQUAD_LW_CHECK].sum(0),
                                  rad[NQUAD_LW_DOUBLE].sum(0), NQUAD_LW, NQUAD_LW_CHECK,
                                  NQUAD_LW_DOUBLE)
    check("longwave cloudy line integral at the quadrature angles = PythonicDISORT's intensity",
          np.all(node_rel < NODE_TOL_LW * np.array([1.0, 1.0, NODE_TOL_DOUBLE])),
          "max difference of the g-point's largest intensity, all g-points: "
          + ", ".join(f"{e:.2e} at {q}" for e, q in zip(node_rel, streams)) + " streams")
    floor = FLUX_FLOOR * np.pi * b_sfc
    rel = np.abs(flux_int - flux_pd) / np.maximum(flux_pd, floor[:, None])
    rel_file = np.abs(flux_int.sum(0) / [up_file, dn_file] - 1)
    check("longwave cloudy TOA flux_up and surface flux_down from the radiances = "
          "PythonicDISORT's per g-point and lw_cloudy_reference.txt",
          rel.max() < FLUX_TOL and rel_file.max() < FLUX_TOL,
          f"per g-point max relative difference up {rel[:, 0].max():.2e}, down "
          f"{rel[:, 1].max():.2e}; broadband up {flux_int[:, 0].sum():.6f} (file {up_file:.6f}), "
          f"down {flux_int[:, 1].sum():.6f} (file {dn_file:.6f}) W m-2, relative differences "
          f"{rel_file[0]:.1e}, {rel_file[1]:.1e}")
    fine = np.array([solve_lw(optics[g][0], b_top[:, g], b_bot[:, g], b_sfc[g], emis, NQUAD_LW,
                              mu, ssa=optics[g][1], chi=optics[g][2], h0=2e-4, npt=16)["rad"]
                     for g in range(ng)])
    grid = np.max(np.abs(fine.sum(0) / bb - 1))
    check("longwave cloudy t-quadrature converged (finer grid)", grid < GRID_TOL,
          f"broadband max relative change {grid:.2e}")
    return dict(nz=nz, ng=ng, t_sfc=t_sfc, emis=emis, layer=layer, cloud=cloud, mu=mu, rad=bb,
                diff=err, double=d_double)


HEADER = """\
# Broadband reference radiances of the U.S. Standard Atmosphere 1976 column, clear (case us1976)
# and with a gray cloud layer (case us1976_cloud), written by
# bench/broadband/make_radiance_reference.py (see its header and README.md in this folder) with
# PythonicDISORT {pd}: discrete ordinates per g-point, radiances at the angles below by
# integrating the source function along the line of sight, summed over the g-points. Both cases
# use the per-g-point gas optics of case us1976 of sw_gpoint_reference.txt and
# lw_gpoint_reference.txt unchanged.
# Shortwave: {sw_ng} g-points, beam at mu0 = {mu0} of the column's TSI {tsi} W m-2, Rayleigh
# phase function 3/4 (1 + cos^2 Theta), Lambert surface albedo {albedo}, no diffuse light from
# above; DIFFUSE radiance only (the direct beam is excluded). Longwave: {lw_ng} g-points, Planck
# radiance linear in optical depth inside each layer, Lambert surface of emissivity {emis} at
# {tsfc} K, nothing from above.
# Case us1976_cloud, the column of sw_cloudy_reference.txt and lw_cloudy_reference.txt: a gray
# cloud in layer {layer} (sw_cloud, lw_cloud lines) with a Henyey-Greenstein phase function,
# mixed with the gas as kumo mixes the components of a layer (optical depths add, scattering
# optical depths add, the phase function is the scattering-weighted mean of Rayleigh's and the
# cloud's, a layer emits (1 - ssa) times its Planck source); solved with delta-M (moments
# 0..streams-1 kept), the single scattering of the beam with the exact phase function
# (Nakajima-Tanaka TMS).
# Directions (kumo's convention): the direction in which light TRAVELS. mu = cosine from the
# upward vertical, mu > 0 travelling up (seen by a downward-looking sensor), mu < 0 travelling
# down (seen by an upward-looking sensor). Relative azimuth = azimuth of the travel direction
# minus the azimuth towards which the sun's beam travels (degrees). The beam travels along
# Omega0 = (sqrt(1 - mu0^2), 0, -mu0); cos_theta = Omega . Omega0
#   = -mu mu0 + sqrt(1 - mu^2) sqrt(1 - mu0^2) cos(azimuth): +1 forward, -1 backscatter.
# Levels as in kumo: 0 = surface (radiance just above the surface, travelling down), nz = top
# of the atmosphere (travelling up). Units: radiance W m-2 sr-1, temperature K, TSI W m-2.
# Blocks (one keyword at the start of each line, whitespace-separated numbers):
#   case <column> <nz>
#   sw_setup <mu0> <surface albedo> <TSI> <streams> <check streams> <n g-points>
#   sw_cloud <layer> <optical depth> <single-scattering albedo> <g>   (case us1976_cloud)
#   sw_radiance <level> <mu> <relative azimuth deg> <cos_theta> <radiance> <|radiance - check|>
#   lw_setup <surface temperature> <surface emissivity> <streams> <check streams> <n g-points>
#   lw_cloud <layer> <optical depth> <single-scattering albedo> <g>   (case us1976_cloud)
#   lw_radiance <level> <mu> <radiance> <|radiance - check|>
#   end
# <radiance> is computed with <streams>, the last column is its absolute difference to the same
# computation with <check streams>, the reference's accuracy estimate. The clear longwave
# radiances going down at the surface do not depend on the stream number (no scattering,
# nothing reflected from above: exact line integrals of the stored optics), hence 0 there.
# Case us1976_cloud: the estimate is at most {sw_err:.1e} relative in the shortwave and
# {lw_err:.1e} in the longwave{flagged}; with twice <streams> ({sw_nd} shortwave, {lw_nd}
# longwave) the radiances move by at most {sw_d:.1e} and {lw_d:.1e} relative, at most
# {ratio:.2f} of the estimate.
"""


def flagged_text(sw, lw):
    """The cloudy directions whose error estimate exceeds ERROR_FLAG of the radiance."""
    bad = [f"SW level {sw['level'][i]} mu {m:g} azimuth {p:g}"
           for i, (m, p) in enumerate(zip(sw["mu"], sw["ph"]))
           if sw["diff"][i] > ERROR_FLAG * sw["rad"][i]]
    bad += [f"LW level {lw['level'][i]} mu {m:g}" for i, m in enumerate(lw["mu"])
            if lw["diff"][i] > ERROR_FLAG * lw["rad"][i]]
    if not bad:
        return f" (below {ERROR_FLAG:g} everywhere)"
    return f"; above {ERROR_FLAG:g} (less accurate) at: " + "; ".join(bad)


def write_case(out, name, sw, lw):
    level = {"top": sw["nz"], "surface": 0}
    out.write(f"case {name} {sw['nz']}\n")
    out.write(f"sw_setup {sw['mu0']!r} {sw['albedo']!r} {sw['tsi']!r} {NQUAD_SW} "
              f"{NQUAD_SW_CHECK} {sw['ng']}\n")
    if "cloud" in sw:
        out.write(f"sw_cloud {sw['layer']} " + " ".join(repr(v) for v in sw["cloud"]) + "\n")
    for (lev, m, p), r, d, c in zip(SW_DIRS, sw["rad"], sw["diff"], sw["ct"]):
        out.write(f"sw_radiance {level[lev]} {m!r} {p!r} {c:.10e} {r:.10e} {d:.3e}\n")
    out.write(f"lw_setup {lw['t_sfc']!r} {lw['emis']!r} {NQUAD_LW} {NQUAD_LW_CHECK} "
              f"{lw['ng']}\n")
    if "cloud" in lw:
        out.write(f"lw_cloud {lw['layer']} " + " ".join(repr(v) for v in lw["cloud"]) + "\n")
    for (lev, m), r, d in zip(LW_DIRS, lw["rad"], lw["diff"]):
        out.write(f"lw_radiance {level[lev]} {m!r} {r:.10e} {d:.3e}\n")
    out.write("end\n")


def print_case(name, sw, lw):
    print(f"broadband radiances of {name} (W m-2 sr-1), |difference to half the streams|"
          + (", |difference to twice the streams|:" if "double" in sw else ":"))
    for i, ((lev, m, p), r, d, c) in enumerate(zip(SW_DIRS, sw["rad"], sw["diff"], sw["ct"])):
        extra = (f"  {sw['double'][i]:.2e} ({sw['double'][i] / r:.1e}); Theta "
                 f"{np.degrees(np.arccos(c)):5.1f} deg, exact single scattering "
                 f"{sw['tms'][i]:+.1e}" if "double" in sw else "")
        print(f"  SW {lev:7s} mu {m:+.1f} phi {p:5.1f} cosT {c:+.4f}: {r:.10e}  {d:.2e} "
              f"({d / r:.1e}){extra}")
    for i, ((lev, m), r, d) in enumerate(zip(LW_DIRS, lw["rad"], lw["diff"])):
        extra = (f"  {lw['double'][i]:.2e} ({lw['double'][i] / r:.1e})" if "double" in lw
                 else "")
        print(f"  LW {lev:7s} mu {m:+.1f}: {r:.10e}  {d:.2e} ({d / r:.1e}){extra}")


def main():
    t0 = time.time()
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(DATA, "radiance_reference.txt")
    version = metadata.version("PythonicDISORT")
    print(f"PythonicDISORT {version}")
    convention_checks()
    sw = run_sw()
    lw = run_lw()
    sw_c = run_sw_cloudy()
    lw_c = run_lw_cloudy()
    for res, dirs in ((sw_c, SW_DIRS), (lw_c, LW_DIRS)):
        res["level"] = [sw_c["nz"] if d[0] == "top" else 0 for d in dirs]
    print_case(CASE, sw, lw)
    print_case(CLOUD_CASE, sw_c, lw_c)
    print(f"({time.time() - t0:.0f} s)")
    if failures:
        print(f"FAILED checks: {', '.join(failures)}; nothing written")
        sys.exit(1)
    ratio = max(np.max(r["double"] / r["diff"]) for r in (sw_c, lw_c))
    with open(out_path, "w") as out:
        out.write(HEADER.format(
            pd=version, sw_ng=sw["ng"], mu0=sw["mu0"], tsi=sw["tsi"], albedo=sw["albedo"],
            lw_ng=lw["ng"], emis=lw["emis"], tsfc=lw["t_sfc"], layer=sw_c["layer"],
            sw_err=np.max(sw_c["diff"] / sw_c["rad"]), lw_err=np.max(lw_c["diff"] / lw_c["rad"]),
            flagged=flagged_text(sw_c, lw_c), sw_nd=NQUAD_SW_DOUBLE, lw_nd=NQUAD_LW_DOUBLE,
            sw_d=np.max(sw_c["double"] / sw_c["rad"]), lw_d=np.max(lw_c["double"] / lw_c["rad"]),
            ratio=ratio))
        write_case(out, CASE, sw, lw)
        write_case(out, CLOUD_CASE, sw_c, lw_c)
    print(f"wrote {os.path.relpath(out_path)} ({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
