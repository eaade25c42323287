"""Monte Carlo estimates and their standard errors, from the sums a render accumulates.

Samples within one pass are independent, but the hybrid integrator builds its beams once per
pass (for one sun direction drawn in the disk, and below a rough sea one sub-pixel facet), so
samples of one pass share that draw: the per-sample variance misses the spread between passes.
Each sensor's error is therefore estimated from how its passes are drawn:

- **Radiometers (hybrid, with a sun): paired strata.** Passes come in pairs; the pair k draws
  its two sun directions independently in the k-th of K equal parts of the disk (strata). The
  estimate is the mean of the pass means (each stratum weighs 1/K), and its variance is
  estimated without bias from the pairs' differences, sum_k (y_k1 - y_k2)^2 / (4 K^2)
  (Cochran 1977, sec. 5A.12: two units per stratum). It holds both the samples' own noise and
  the spread between directions, and keeps most of what stratifying the disk gains. The
  reported error is the larger of it and the per-sample one (which it must exceed but for
  noise; with few pairs the per-sample one is the steadier).
- **Cameras: independent samples.** A pixel's error is its samples' own spread,
  var(mean) = s^2 / N, in both integrators. Each hybrid pass draws its sun direction (and a
  rough sea's facet) independently, so samples of one pass share that draw; but measured over
  12-16 seeds (docs/verification.md) the between-pass part is negligible for pixels (the spread
  of the seeds' means over this estimate: 0.98-1.01 in variance on the examples, under waves
  with and without the sun-disk blur and below a rough sea; 1.07 under a 10 deg sun, whose
  caustics move between passes). The one-way random-effects estimate that split within- and
  between-pass parts (``image_variance`` with ``b``; Searle, Casella & McCulloch 1992, ch. 3)
  clipped its noisy between-pass part at zero and so read 1.8-2.9x the variance on all of
  them; it is no longer used for images.
- **Everything else** (path tracing, no sun): independent samples, var(mean) = s^2 / N.

An error is flagged as not to be trusted when it rests on too little (fewer than MIN_STRATA
complete pairs; an image pixel with fewer than 2 samples has no variance at all: inf) or when
the samples' distribution has heavy tails: the relative variance of the variance,
VOV = sum d^4 / (sum d^2)^2 - 1/N (d: deviations from the mean), above VOV_LIMIT (the limit
MCNP uses, X-5 Monte Carlo Team 2003, vol. I, sec. 2.VI.D), as in the exact mode (forward
cone 0) where rare paths scatter twice in the phase function's forward peak.
"""
from __future__ import annotations

import numpy as np

MIN_STRATA = 4      # complete pairs of passes below which a paired error is not trusted
VOV_LIMIT = 0.1     # relative variance of the variance above which tails are too heavy


def mean_stderr(s: np.ndarray, s2: np.ndarray, n) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error of the mean of independent samples from their sums."""
    n = np.asarray(n, dtype=np.float64)
    nn = np.maximum(n, 1.0)
    mean = s / nn
    var = np.maximum(s2 / nn - mean * mean, 0.0) * nn / np.maximum(nn - 1.0, 1.0)
    return mean, np.sqrt(var / nn)


def merge_moments(a: tuple, b: tuple) -> tuple:
    """(n, mean, M2, M3, M4) of two sets merged (central sums of powers; Pebay 2008)."""
    na, ma, a2, a3, a4 = a
    nb, mb, b2, b3, b4 = b
    nn = na + nb
    safe = np.where(nn > 0, nn, 1.0)
    d = mb - ma
    d2 = d * d
    m4 = (a4 + b4 + d2 * d2 * na * nb * (na * na - na * nb + nb * nb) / safe ** 3
          + 6.0 * d2 * (na * na * b2 + nb * nb * a2) / safe ** 2 + 4.0 * d * (na * b3 - nb * a3) / safe)
    m3 = a3 + b3 + d2 * d * na * nb * (na - nb) / safe ** 2 + 3.0 * d * (na * b2 - nb * a2) / safe
    m2 = a2 + b2 + d2 * na * nb / safe
    mean = ma + d * nb / safe
    return nn, mean, m2, m3, m4


def variance_of_variance(n, m2, m4) -> np.ndarray:
    """VOV = M4 / M2^2 - 1/N: the relative variance of the estimated variance (0 where the
    samples do not vary)."""
    n = np.asarray(n, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(m2 > 0, m4 / np.where(m2 > 0, m2, 1.0) ** 2 - 1.0 / np.maximum(n, 1.0), 0.0)
    return np.maximum(v, 0.0)


def bin_counts(total: int, nbins: int) -> np.ndarray:
    """Samples per bin of [0, total) when sample i goes to bin i % nbins."""
    counts = np.full(nbins, total // nbins, dtype=np.int64)
    counts[: total % nbins] += 1
    return counts


def pass_bin_counts(start: int, n: int, nbins: int) -> np.ndarray:
    """Samples per bin of the pass [start, start + n)."""
    return bin_counts(start + n, nbins) - bin_counts(start, nbins)


class RadiometerSums:
    """What one radiometer's passes add up to in one round of one render.

    Arrays are (bins, components + 1, bands) like the core's; the band axis is filled band
    group by band group (``g``: a slice of bands). ``paired``: the passes are paired strata
    (``strata`` pairs: pass 2k and 2k + 1 in stratum k).
    """

    def __init__(self, shape: tuple, paired: bool, strata: int):
        nbins, _, nb = shape
        self.paired, self.strata = paired, strata
        self.s, self.s2 = np.zeros(shape), np.zeros(shape)
        self.samples = np.zeros(nb, dtype=np.int64)         # per band (its group's passes)
        # the total's moments over all samples, per bin and band: n, mean, M2, M3, M4
        self.mom = tuple(np.zeros((nbins, nb)) for _ in range(5))
        self.has_moments = np.ones(nb, dtype=bool)
        # paired strata: sum of the pairs' means, of their squared differences, the pending
        # first pass of the open pair, and the complete pairs (per band)
        self.pair_mean, self.pair_sq = np.zeros(shape), np.zeros(shape)
        self.pending = np.zeros(shape)
        self.pairs = np.zeros(nb, dtype=np.int64)
        # sum over passes of (pass sum)^2 / pass samples, per bin: the within-pass variance
        self.b = np.zeros(shape)
        self.empty_bins = np.zeros(nbins, dtype=bool)       # a pass without samples in the bin

    def add_pass(self, g: slice, index: int, start: int, n: int, s: np.ndarray, s2: np.ndarray,
                 moments: np.ndarray | None) -> None:
        """Pass ``index`` (samples [start, start + n)) of band group ``g``: its sums s, s2 and
        the total's central moments (bins, 3, bands of g), or None when not measured."""
        self.s[..., g] += s
        self.s2[..., g] += s2
        self.samples[g] += n
        nbins = s.shape[0]
        counts = pass_bin_counts(start, n, nbins).astype(np.float64)
        if moments is None:
            self.has_moments[g] = False
        else:
            c = np.broadcast_to(counts[:, None], s.shape[::2])
            with np.errstate(divide="ignore", invalid="ignore"):
                mean = np.where(c > 0, s[:, 0, :] / np.where(c > 0, c, 1.0), 0.0)
            cur = tuple(m[..., g] for m in self.mom)
            merged = merge_moments(cur, (c, mean, moments[:, 0], moments[:, 1], moments[:, 2]))
            for m, v in zip(self.mom, merged):
                m[..., g] = v
        if self.paired:
            self.empty_bins |= counts == 0
            with np.errstate(divide="ignore", invalid="ignore"):
                y = np.where(counts[:, None, None] > 0, s / np.maximum(counts, 1.0)[:, None, None], 0.0)
            self.b[..., g] += s * y
            if index % 2 == 0:
                self.pending[..., g] = y
            else:
                first = self.pending[..., g]
                self.pair_mean[..., g] += 0.5 * (first + y)
                self.pair_sq[..., g] += (first - y) ** 2
                self.pairs[g] += 1

    def estimate(self, tails: bool = True) -> dict:
        """mean, stderr (bins, components + 1, bands); reliable (bins, bands); notes (list).
        ``tails``: flag heavy tails from this round's moments (combine_round_sums judges rounds
        together on their merged moments instead)."""
        nbins = self.s.shape[0]
        counts = np.stack([bin_counts(int(t), nbins) for t in self.samples], axis=-1)[:, None, :]
        mean, err = mean_stderr(self.s, self.s2, counts)
        reliable = np.ones((nbins, self.s.shape[2]), dtype=bool)
        notes = []
        sampled = self.samples > 0
        if not np.all(sampled):
            # bands of a group not rendered (a render stopped early; a round of an adaptive
            # render that needed no more samples there, which combine_round_sums weighs 0)
            notes.append("bands without samples")
            reliable[:, ~sampled] = False
        if self.paired:
            k = self.pairs.astype(np.float64)
            complete = bool(np.all(self.pairs[sampled] == self.strata)) and self.strata > 0
            if complete:
                # The per-sample floor: the pooled within-pass variance over N (a lower bound
                # of the pairs' estimate's expectation; steadier where few pairs are).
                n_all = counts.astype(np.float64)
                passes = 2.0 * k
                kk = np.maximum(k, 1.0)
                with np.errstate(divide="ignore", invalid="ignore"):
                    within = np.where(n_all > passes, np.maximum(self.s2 - self.b, 0.0) /
                                      np.maximum(n_all - passes, 1.0), 0.0) / np.maximum(n_all, 1.0)
                mean = np.where(sampled, self.pair_mean / kk, mean)
                err = np.where(sampled, np.sqrt(np.maximum(self.pair_sq / (4.0 * kk * kk), within)), err)
            else:
                # A render stopped before its last pair: the strata done cover part of the
                # disk only; the per-sample error is all there is.
                notes.append("incomplete passes")
                reliable[:] = False
            few = (self.pairs < MIN_STRATA) & sampled
            if np.any(few):
                notes.append("too few passes")
                reliable[:, few] = False
            if np.any(self.empty_bins):
                notes.append("bins without samples in a pass")
                reliable[self.empty_bins] = False
        n, _, m2, _, m4 = self.mom
        vov = variance_of_variance(n, m2, m4)
        if tails:
            _flag_heavy_tails(vov, self.has_moments, reliable, notes)
        return {"mean": mean, "stderr": err, "reliable": reliable, "vov": vov, "notes": notes,
                "samples": int(self.samples.min()) if self.samples.size else 0}


def _flag_heavy_tails(vov: np.ndarray, has_moments: np.ndarray, reliable: np.ndarray,
                      notes: list) -> None:
    heavy = (vov > VOV_LIMIT) & has_moments[None, :]
    if np.any(heavy):
        notes.append("heavy tails")
        reliable &= ~heavy


def combine_round_sums(rounds: list[RadiometerSums]) -> dict:
    """One radiometer's rounds (independent renders with their own seeds, of any sizes, each
    covering some of the bands) as one estimate, like RadiometerSums.estimate.

    Per band, the rounds that sampled it are weighted by their sample counts (the mean of all
    samples but for the strata's weights); the variance is the sum of the weighted rounds'.
    Tails are judged on the moments of all samples merged (a round too small to show a rare
    path's weight no longer hides it), the other flags round by round."""
    if len(rounds) == 1:
        return rounds[0].estimate()
    ests = [r.estimate(tails=False) for r in rounds]
    w = np.stack([r.samples.astype(np.float64) for r in rounds])      # (rounds, bands)
    total = w.sum(axis=0)
    w = w / np.where(total > 0, total, 1.0)
    mean = sum(wi * e["mean"] for wi, e in zip(w, ests))
    err = np.sqrt(sum((wi * e["stderr"]) ** 2 for wi, e in zip(w, ests)))
    reliable = np.logical_and.reduce([e["reliable"] | (r.samples == 0)[None, :]
                                      for r, e in zip(rounds, ests)])
    notes = ["bands without samples"] if np.any(total == 0) else []
    for r, e in zip(rounds, ests):
        if np.any(r.samples > 0):
            notes += [n for n in e["notes"] if n not in notes and n != "bands without samples"]
    reliable[:, total == 0] = False
    mom = rounds[0].mom
    for r in rounds[1:]:
        mom = merge_moments(mom, r.mom)
    n, _, m2, _, m4 = mom
    vov = variance_of_variance(n, m2, m4)
    has_moments = np.logical_and.reduce([r.has_moments | (r.samples == 0) for r in rounds])
    _flag_heavy_tails(vov, has_moments, reliable, notes)
    return {"mean": mean, "stderr": err, "reliable": reliable, "vov": vov, "notes": notes,
            "samples": int(total.min()) if total.size else 0}


class CameraSums:
    """Per-pixel sums of one camera: (H, W, components + 1, bands) s, the total's sums of
    squares s2 (H, W, 1, bands: the components' are not needed, and at 1920 x 1080 with 10
    bands they would take 660 MB), and for the between-pass analysis b = sum over passes of
    (pass sum of the total)^2 / pass size.

    With adaptive sampling (``add_pass`` given an active mask) pixels take different passes:
    ``n`` (samples), ``passes`` and ``sum_n2`` (sum of squared pass sizes) per pixel."""

    def __init__(self, shape: tuple, between: bool):
        self.s, self.s2 = np.zeros(shape), np.zeros(shape[:2] + (1,) + shape[3:])
        self.b = np.zeros(shape[:2] + shape[3:]) if between else None
        self.sizes: list[int] = []     # pass sizes (band group 0)
        self.n = np.zeros(shape[:2], np.int64)
        self.passes = np.zeros(shape[:2], np.int64)
        self.sum_n2 = np.zeros(shape[:2])
        self.adaptive = False          # whether some pass skipped some pixels
        self.partial = False           # a pass is under way: some rows have taken it, some not

    def copy(self, stride: int = 1) -> "CameraSums":
        """A copy; ``stride`` > 1: of every stride-th row and column only."""
        k = slice(None, None, max(1, int(stride)))
        c = CameraSums.__new__(CameraSums)
        c.s, c.s2 = self.s[k, k].copy(), self.s2[k, k].copy()
        c.b = None if self.b is None else self.b[k, k].copy()
        c.sizes = list(self.sizes)
        c.n, c.passes, c.sum_n2 = self.n[k, k].copy(), self.passes[k, k].copy(), self.sum_n2[k, k].copy()
        c.adaptive, c.partial = self.adaptive, self.partial
        return c

    def add_pass(self, g: slice, s: np.ndarray, s2: np.ndarray, n: int, first_group: bool,
                 active: np.ndarray | None = None, rows: tuple[int, int] | None = None,
                 new_pass: bool = True, last_piece: bool = True) -> None:
        """A pass of ``n`` samples per pixel over band group ``g``, or a piece of one: rows
        (first, end) only (s, s2 hold those rows), ``new_pass`` on its first piece,
        ``last_piece`` on its last (until then ``partial``: pixels differ in samples).
        ``active`` (H, W): the pixels that took it (None: all)."""
        r = slice(None) if rows is None else slice(*rows)
        self.s[r, :, :, g] += s
        self.s2[r, :, :, g] += s2[:, :, :1, :]
        if self.b is not None:
            self.b[r, :, g] += s[:, :, 0, :] ** 2 / n
        if first_group:
            took = 1 if active is None else (np.asarray(active)[r] != 0)
            self.n[r] += n * took
            self.passes[r] += took
            self.sum_n2[r] += float(n) * n * took
            if new_pass:
                self.sizes.append(int(n))
                self.adaptive = self.adaptive or (active is not None and not np.all(active))
            self.partial = not last_piece


def image_variance(s: np.ndarray, s2: np.ndarray, n, b: np.ndarray | None = None,
                   sizes: list[int] | None = None, passes=None, sum_n2=None) -> np.ndarray:
    """Variance of each pixel's mean of its total (H, W, bands); inf where it cannot be
    estimated (fewer than 2 samples).

    s, s2: the total's sums (H, W, bands); with b and the pass sizes (passes of independent
    beams), the random-effects estimate of within- and between-pass variance. ``n`` may be a
    number or an (H, W) array of samples per pixel; with per-pixel ``passes`` and ``sum_n2``
    (adaptive sampling) each pixel's own passes count."""
    N = np.asarray(n, dtype=np.float64)
    if passes is None:
        if N.ndim == 0 and N < 2:
            return np.full(s.shape, np.inf)
        if b is None or sizes is None or len(sizes) < 2 or sum(sizes) != int(N.max()):
            mean, err = mean_stderr(s, s2, N[..., None] if N.ndim else N)
            out = err * err
            return np.where((N[..., None] if N.ndim else N) < 2, np.inf, out)
        P = np.full(N.shape, float(len(sizes)))
        SN2 = np.full(N.shape, float(sum(x * x for x in sizes)))
    else:
        P, SN2 = np.asarray(passes, np.float64), np.asarray(sum_n2, np.float64)
    N3, P3, SN23 = N[..., None], P[..., None], SN2[..., None]
    mean, err = mean_stderr(s, s2, N3)
    plain = err * err
    if b is None:
        return np.where(N3 < 2, np.inf, plain)
    # Random effects (where a pixel has 2+ passes and more samples than passes).
    with np.errstate(divide="ignore", invalid="ignore"):
        within = np.maximum(s2 - b, 0.0) / np.maximum(N3 - P3, 1.0)
        between_ss = np.maximum(b - s * s / np.maximum(N3, 1.0), 0.0)
        sb2 = (between_ss - (P3 - 1) * within) / np.maximum(N3 - SN23 / np.maximum(N3, 1.0), 1e-300)
        anova = within / np.maximum(N3, 1.0) + np.maximum(sb2, 0.0) * SN23 / np.maximum(N3 * N3, 1.0)
    use = (P3 >= 2) & (N3 > P3)
    out = np.where(use, anova, plain)
    return np.where(N3 < 2, np.inf, out)
