"""Spectral bands of a Blender scene and the mapping between bands and Blender's RGB.

Colours (base colours, lamp and world colours) map to bands by the nearest primary: a band
below 490 nm takes blue, 490-580 nm green, above 580 nm red. Images of the RGB preset show its
bands as red, green and blue (one band: grey); any other band set is shown through the CIE 1931
colour-matching functions (``photic.colour``).
"""
from __future__ import annotations

import math

import numpy as np

RGB_BANDS = ((620.0, 80.0), (550.0, 60.0), (460.0, 80.0))  # centre, width (nm): R, G, B
_DISPLAY_NM = (620.0, 550.0, 460.0)


class BandError(ValueError):
    """A bad band list: ``prop`` is the scene property, the message says what is wrong."""

    def __init__(self, prop: str, message: str):
        super().__init__(prop, message)
        self.prop = prop
        self.message = message


def parse_number_list(text: str, what: str) -> list[float]:
    """Numbers separated by commas or spaces; raises ValueError naming the bad item."""
    items = [t for t in text.replace(",", " ").split() if t]
    values = []
    for i, t in enumerate(items):
        try:
            x = float(t)
        except ValueError:
            raise ValueError(f"item {i + 1} of {what} ({t!r}) is not a number") from None
        values.append(x)
    return values


def _band_ranges():
    """The declared ranges of a band's centre and width (``photic.parameters``)."""
    from photic.parameters import PARAMETERS
    return PARAMETERS["band.center_nm"], PARAMETERS["band.width_nm"]


def scene_bands(props) -> list[tuple[str, float, float]]:
    """(name, centre_nm, width_nm) of each band from ``Scene.photic``."""
    if props.bands == "RGB":
        return [(f"{c:g}", c, w) for c, w in RGB_BANDS]
    if props.bands == "SINGLE":
        c, w = props.band_center_nm, props.band_width_nm
        return [(f"{c:g}", c, w)]
    bands = []
    for i, item in enumerate(t for t in props.custom_bands.split(",") if t.strip()):
        parts = item.replace(":", " ").split()
        try:
            c, w = (float(parts[0]), float(parts[1])) if len(parts) == 2 else (float(parts[0]), 10.0)
            if len(parts) > 2:
                raise ValueError
        except (ValueError, IndexError):
            raise BandError("custom_bands", f"band {i + 1} ({item.strip()!r}) must be "
                                            f"'centre_nm:width_nm' or 'centre_nm'") from None
        centre, width = _band_ranges()
        if not (math.isfinite(c) and centre.contains(c)):
            raise BandError("custom_bands", f"band {i + 1}: centre {c:g} nm is outside "
                                            f"{centre.lo:g}-{centre.hi:g} nm")
        if not (math.isfinite(w) and width.contains(w)):
            raise BandError("custom_bands", f"band {i + 1}: width {w:g} nm is outside "
                                            f"{width.lo:g}-{width.hi:g} nm")
        bands.append((f"{c:g}", c, w))
    if not bands:
        raise BandError("custom_bands", "is empty: give at least one band, e.g. '450:20, 550:20'")
    names = [b[0] for b in bands]
    if len(set(names)) != len(names):
        raise BandError("custom_bands", "lists the same band centre twice")
    return bands


def _primary(center_nm: float) -> int:
    """Index into (R, G, B) of the primary a band takes its colour from."""
    return 2 if center_nm < 490.0 else (1 if center_nm <= 580.0 else 0)


def rgb_to_bands(rgb, bands) -> np.ndarray:
    """Per-band values from an RGB triple (nearest primary per band)."""
    rgb = [float(x) for x in rgb[:3]]
    return np.array([rgb[_primary(c)] for _, c, _ in bands])


def display_indices(bands) -> list[int]:
    """Band index shown as R, G and B."""
    centres = np.array([c for _, c, _ in bands])
    return [int(np.argmin(np.abs(centres - nm))) for nm in _DISPLAY_NM]


def _display_matrix(bands):
    """(nbands, 3) matrix to display RGB, or None for a direct pick of bands.

    The RGB preset and single bands show bands directly; any other set of bands goes through
    the CIE 1931 colour-matching functions (``photic.colour``, white-balanced so that a flat
    spectrum is grey), falling back to the nearest bands when they miss the visible range."""
    if len(bands) == 1 or [(c, w) for _, c, w in bands] == [tuple(b) for b in RGB_BANDS]:
        return None
    try:
        from photic.colour import band_matrix
        return band_matrix([(c, w) for _, c, w in bands])
    except (ImportError, ValueError):
        return None


def bands_to_rgba(image: np.ndarray, bands, variance: bool = False) -> np.ndarray:
    """(H, W, nbands) -> (H, W, 4) float32 with alpha 1: display RGB (see _display_matrix).

    ``variance``: the image holds variances; they combine with the squared weights (as for
    independent bands; bands traced along the same paths are correlated, which this ignores)."""
    h, w = image.shape[:2]
    out = np.ones((h, w, 4), np.float32)
    m = _display_matrix(bands)
    if m is None:
        out[:, :, :3] = image[:, :, display_indices(bands)]
    else:
        w = m * m if variance else m
        finite = np.isfinite(image)
        out[:, :, :3] = np.where(finite, image, 0.0) @ w
        # an unknown (infinite) variance stays infinite in every channel it weighs in (inf
        # times a zero weight would be NaN)
        if not np.all(finite):
            out[:, :, :3][((~finite).astype(float) @ (w != 0)) > 0] = np.inf
    return out


MID_GREY = 0.18
EXPOSURE_LIMIT = 16.0  # stops


def auto_exposure(rgb: np.ndarray) -> float | None:
    """Stops of display exposure that show an image's average brightness as mid-grey: log2 of
    0.18 over the image's key (the geometric mean of its luminance, Reinhard et al. 2002, over
    the pixels with light; values below a millionth of the brightest count as that). None for a
    black or non-finite image."""
    rgb = np.asarray(rgb, float)[..., :3]
    y = 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]
    y = y[np.isfinite(y) & (y > 0)]
    if y.size == 0:
        return None
    y = np.maximum(y, 1e-6 * float(y.max()))
    key = float(np.exp(np.mean(np.log(y))))
    stops = math.log2(MID_GREY / key)
    return float(np.clip(round(stops * 20.0) / 20.0, -EXPOSURE_LIMIT, EXPOSURE_LIMIT))


def total_to_rows(total: np.ndarray, n, bands) -> np.ndarray:
    """A render view's Combined pixels from a camera's running sums of the total (H, W, bands)
    and samples per pixel (a number or (H, W)): display RGB with alpha 1, float32, bottom row
    first, flat (what ``set_rect`` takes). The band-to-RGB step is done on the sums before the
    division (three channels to divide instead of every band)."""
    h, w = total.shape[:2]
    m = _display_matrix(bands)
    rgb = total[:, :, display_indices(bands)] if m is None else total @ m
    nn = np.maximum(np.asarray(n, float), 1.0)
    rgb = rgb / (nn[:, :, None] if nn.ndim else nn)
    out = np.ones((h, w, 4), np.float32)
    out[:, :, :3] = rgb[::-1]
    return out.reshape(h * w, 4)
