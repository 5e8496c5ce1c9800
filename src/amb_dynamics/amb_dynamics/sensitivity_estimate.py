"""Measured sensitivity from an injection record (ISO 14839-3): H1 estimate with coherence from Welch spectra.

The controller adds a known disturbance E_k to the sampled sensor signal of one axis and records the disturbed
signal y_m,k = y_k + E_k.  Then S = Y_m/E, estimated as H1 = G_E,ym / G_E,E from Welch-averaged cross and auto
spectra (scipy.signal.csd / welch), with the magnitude-squared coherence

    gamma^2 = |G_E,ym|^2 / (G_E,E G_ym,ym)

saying where the estimate is trustworthy.  Noise that is not caused by E (sensor noise, unbalance, base motion)
leaves H1 unbiased and lowers gamma^2.  Its random error: the normalised standard deviation of |H1| from n_d
averages is sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_d)) (Bendat and Piersol, Random Data, the H1 magnitude
estimate), computed per bin with the estimated coherence (``random_error``).  It is the spread of a periodic
injection analysed one period per segment; leakage (a non-periodic injection in Hann segments) adds a bias it
does not include.  A single-segment FFT ratio Y/E would have gamma^2 = 1 by construction and
is refused: at least ``MIN_SEGMENTS`` averages are required.  The frequency resolution is fs/nperseg; a peak whose
half-power band spans fewer than ``RESOLVED_BINS`` bins (a lightly damped mode) is reported as unresolved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from .errors import InputError

MIN_SEGMENTS = 4
INJECTED_FLOOR = 1e-6  # bins with less injected power (relative to the largest) are left out
RESOLVED_BINS = 5  # contiguous bins above half power for a resolved peak (Hann main lobe: +-2 bins)


@dataclass(frozen=True)
class MeasuredSensitivity:
    """H1 estimate of S on the one-sided frequency grid of the Welch segments (within the band, if given)."""

    frequency_hz: np.ndarray
    S: np.ndarray  # complex
    coherence: np.ndarray
    resolution_hz: float
    segments: int

    @property
    def abs(self) -> np.ndarray:
        return np.abs(self.S)

    @property
    def phase_deg(self) -> np.ndarray:
        return np.degrees(np.angle(self.S))

    @property
    def random_error(self) -> np.ndarray:
        """Normalised random error of |S| per bin, sqrt(1 - gamma^2) / (|gamma| sqrt(2 segments)); inf where the
        coherence is 0."""
        g2 = self.coherence
        with np.errstate(divide="ignore"):
            return np.sqrt(1.0 - g2) / (np.sqrt(g2) * np.sqrt(2.0 * self.segments))

    def peak(self, min_coherence: float = 0.9) -> dict:
        """Largest |S| among the bins with coherence >= min_coherence, with a resolved/unresolved verdict."""
        ok = np.flatnonzero(self.coherence >= min_coherence)
        if ok.size == 0:
            return {"peak_abs": None, "peak_hz": None, "resolved": False, "reason": "no bin reaches the coherence"}
        i = int(ok[np.argmax(self.abs[ok])])
        above = self.abs >= self.abs[i] / np.sqrt(2.0)
        lo, hi = i, i
        while lo > 0 and above[lo - 1]:
            lo -= 1
        while hi < above.size - 1 and above[hi + 1]:
            hi += 1
        inside = hi - lo + 1 >= RESOLVED_BINS and lo > 0 and hi < above.size - 1
        out = {"peak_abs": float(self.abs[i]), "peak_hz": float(self.frequency_hz[i]), "resolved": bool(inside)}
        i_all = int(np.argmax(self.abs))
        if i_all != i:
            out["resolved"] = False
            out["reason"] = (
                f"the largest |S| ({self.abs[i_all]:.4g} at {self.frequency_hz[i_all]:.4g} Hz) has coherence "
                f"{self.coherence[i_all]:.2f} < {min_coherence:g}: a peak narrower than the resolution "
                f"{self.resolution_hz:.3g} Hz (leakage) or too little injected power there; the coherent peak is a "
                "lower bound"
            )
        elif lo == 0 or hi == above.size - 1:
            edge = self.frequency_hz[0] if lo == 0 else self.frequency_hz[-1]
            out["reason"] = (
                f"|S| is still above half its largest value at the band edge {edge:.4g} Hz: the peak may lie "
                "outside the measured band"
            )
        elif not inside:
            out["reason"] = (
                f"the peak spans {hi - lo + 1} bins of {self.resolution_hz:.3g} Hz above half power (resolved needs "
                f"{RESOLVED_BINS}, beyond the window's own main lobe): its height is a lower bound; record longer "
                "(resolution = 1/segment length)"
            )
        return out

    def to_dict(self) -> dict:
        return {
            "frequency_hz": self.frequency_hz.tolist(),
            "abs": self.abs.tolist(),
            "phase_deg": self.phase_deg.tolist(),
            "coherence": self.coherence.tolist(),
            "random_error": [float(v) if np.isfinite(v) else None for v in self.random_error],
            "resolution_hz": self.resolution_hz,
            "segments": self.segments,
        }


def estimate_sensitivity(
    e: np.ndarray,
    ym: np.ndarray,
    fs: float,
    nperseg: int | None = None,
    band_hz: tuple[float, float] | None = None,
    window: str = "hann",
    noverlap: int | None = None,
) -> MeasuredSensitivity:
    """H1 and coherence of ym (disturbed sensor signal) over e (injected disturbance), both sampled at fs (Hz).

    nperseg : samples per Welch segment (default: the record split into 8 segments with 50 % overlap);
    band_hz : keep only lo <= f <= hi;
    window, noverlap : Welch window and overlap (default hann, nperseg // 2); a multisine is analysed with
        ``window="boxcar"``, ``nperseg`` = its period and ``noverlap=0`` (every line on a bin, no leakage).
    """
    e = np.asarray(e, dtype=float)
    ym = np.asarray(ym, dtype=float)
    if e.shape != ym.shape or e.ndim != 1:
        raise InputError(f"injection and disturbed signal must be 1-D of equal length (got {e.shape}, {ym.shape})")
    if not (np.all(np.isfinite(e)) and np.all(np.isfinite(ym))):
        raise InputError("injection record holds NaN or inf samples")
    if nperseg is None:
        nperseg = max(16, e.size * 2 // (MIN_SEGMENTS * 2 + 1))
    noverlap = nperseg // 2 if noverlap is None else noverlap
    segments = 1 + (e.size - nperseg) // (nperseg - noverlap) if e.size >= nperseg else 0
    if segments < MIN_SEGMENTS:
        raise InputError(
            f"record of {e.size} samples gives {segments} Welch segments of {nperseg}: need >= {MIN_SEGMENTS} "
            "(a single-segment ratio has coherence 1 by construction); record longer or shorten the segments"
        )
    kw = {"fs": fs, "window": window, "nperseg": nperseg, "noverlap": noverlap, "detrend": "constant"}
    f, Pee = signal.welch(e, **kw)
    _, Pyy = signal.welch(ym, **kw)
    _, Pey = signal.csd(e, ym, **kw)
    with np.errstate(divide="ignore", invalid="ignore"):
        H1 = Pey / Pee
        coh = np.abs(Pey) ** 2 / (Pee * Pyy)
    keep = Pee > INJECTED_FLOOR * Pee.max()  # bins that carry the injection (a multisine: its lines)
    if band_hz is not None:
        keep &= (f >= band_hz[0]) & (f <= band_hz[1])
    if not keep.any():
        raise InputError("no frequency bin of the record lies in the band with injected power")
    return MeasuredSensitivity(f[keep], H1[keep], np.clip(coh[keep].real, 0.0, 1.0), fs / nperseg, segments)
