"""The fog model against independent transcriptions of the formulas."""
import math

import numpy as np
import pytest

from fogsim.colour import linear_to_srgb, srgb_to_linear
from fogsim.fog.model import (
    Fogger,
    Kernel,
    density_field,
    estimate_airlight,
    koschmieder,
    koschmieder_extended,
    smooth_transmission,
    transmission,
)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def reference_standard(image, dist, beta, airlight):
    """Eq. 2 in float64, pixel by pixel semantics, rounded half up."""
    i = image.astype(np.float64)
    t = np.exp(-beta * dist.astype(np.float64))[..., None]
    return i * t + np.asarray(airlight, np.float64) * (1 - t)


def test_standard_matches_formula_uint8(rng):
    img = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    dist = rng.uniform(0, 150, (37, 53)).astype(np.float32)
    for beta in (0.01, 0.06, 0.12):
        for a in (255, (200, 220, 240)):
            got = koschmieder(img, dist, beta, airlight=a)
            ref = reference_standard(img, dist, beta, a)
            assert got.dtype == np.uint8
            assert np.abs(got.astype(np.float64) - ref).max() <= 0.5 + 1e-3  # correctly rounded
            assert np.mean(got == np.floor(ref + 0.5)) > 0.999


def test_standard_uint16_and_float(rng):
    img16 = rng.integers(0, 65536, (20, 30, 3), dtype=np.uint16)
    dist = rng.uniform(0, 80, (20, 30)).astype(np.float32)
    got = koschmieder(img16, dist, 0.05, airlight=255)
    ref = reference_standard(img16, dist, 0.05, 65535)
    assert got.dtype == np.uint16 and np.abs(got - ref).max() <= 0.5 + 0.01
    imgf = rng.uniform(0, 1, (20, 30, 3)).astype(np.float32)
    got = koschmieder(imgf, dist, 0.05, airlight=(255, 127.5, 0))
    ref = reference_standard(imgf, dist, 0.05, (1.0, 0.5, 0.0))
    assert got.dtype == np.float32 and np.allclose(got, ref, atol=1e-5)


def test_beta_zero_is_identity_and_infinite_distance_is_airlight(rng):
    img = rng.integers(0, 256, (16, 16, 3), dtype=np.uint8)
    dist = rng.uniform(0, 100, (16, 16)).astype(np.float32)
    dist[:4] = np.inf
    assert np.array_equal(koschmieder(img, dist, 0.0), img)
    far = koschmieder(img, np.full((16, 16), np.inf, np.float32), 0.03, airlight=(10, 20, 30))
    assert np.array_equal(far, np.broadcast_to(np.array([10, 20, 30], np.uint8), img.shape))
    near = koschmieder(img, np.zeros((16, 16), np.float32), 0.12)
    assert np.array_equal(near, img)


def test_one_pixel_by_hand():
    img = np.array([[[100, 0, 255]]], np.uint8)
    out = koschmieder(img, np.array([[50.0]], np.float32), 0.03)
    t = math.exp(-1.5)  # 0.22313
    assert out[0, 0].tolist() == [round(100 * t + 255 * (1 - t)), round(255 * (1 - t)), 255]


def test_linear_space_blend(rng):
    img = rng.integers(0, 256, (10, 12, 3), dtype=np.uint8)
    dist = rng.uniform(0, 60, (10, 12)).astype(np.float32)
    got = koschmieder(img, dist, 0.04, airlight=(255, 128, 64), space="linear")
    def lin(c):
        return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    def enc(c):
        return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    t = np.exp(-0.04 * dist.astype(np.float64))[..., None]
    a = lin(np.array([255, 128, 64]) / 255.0)
    ref = enc(lin(img / 255.0) * t + a * (1 - t)) * 255
    assert np.abs(got - ref).max() <= 0.5 + 1e-2
    # linear blending is brighter than sRGB blending for a dark object in fog
    dark = np.zeros((1, 1, 3), np.uint8)
    d = np.array([[20.0]], np.float32)
    assert koschmieder(dark, d, 0.03, space="linear")[0, 0, 0] > koschmieder(dark, d, 0.03)[0, 0, 0]


def test_srgb_round_trip():
    x = np.linspace(0, 1, 1001, dtype=np.float32)
    assert np.allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=2e-6)


def slow_reference_extended(img, dist, beta, weights2d, airlight=255.0):
    """A literal transcription of the reference's windowed accumulation (floats, no rounding):
    every pixel y adds (I(x)·t(y) + A·(1 − t(y)))·w(x − y) to each x in its window."""
    h, w = dist.shape
    r = weights2d.shape[0] // 2
    t = np.exp(-beta * dist.astype(np.float64))
    out = np.zeros(img.shape, np.float64)
    for m in range(r, h - r):
        for n in range(r, w - r):
            win = (slice(m - r, m + r + 1), slice(n - r, n + r + 1))
            out[win] += (img[win].astype(np.float64) * t[m, n] + airlight * (1 - t[m, n])) * weights2d[..., None]
    return out


@pytest.mark.parametrize("kernel", [Kernel("box", 5), Kernel("gaussian", 7, sigma=2.0)])
def test_extended_equals_slow_loop_on_interior(rng, kernel):
    img = rng.integers(0, 256, (24, 30, 3), dtype=np.uint8)
    dist = rng.uniform(1, 90, (24, 30)).astype(np.float32)
    w1 = kernel.weights_1d()
    ref = slow_reference_extended(img, dist, 0.05, np.outer(w1, w1))
    got = koschmieder_extended(img, dist, 0.05, kernel=kernel)
    r = 2 * (kernel.size // 2)  # interior: every pixel whose window gets all contributions
    inner = (slice(r, -r), slice(r, -r))
    assert np.abs(got[inner].astype(np.float64) - ref[inner]).max() <= 0.5 + 1e-3


def test_extended_has_no_dark_border():
    img = np.full((40, 50, 3), 120, np.uint8)
    dist = np.full((40, 50), 30.0, np.float32)
    standard = koschmieder(img, dist, 0.06)
    for kernel in (Kernel("box", 19), Kernel("gaussian", 19, 5.0), Kernel("guided", 9)):
        ext = koschmieder_extended(img, dist, 0.06, kernel=kernel)
        assert np.array_equal(ext, standard), kernel  # uniform t stays uniform, border included


def test_kernel_larger_than_image_is_still_normalised():
    img = np.full((6, 9, 3), 77, np.uint8)
    dist = np.full((6, 9), 12.0, np.float32)
    for kind in ("box", "gaussian"):
        assert np.array_equal(koschmieder_extended(img, dist, 0.05, Kernel(kind, 19)), koschmieder(img, dist, 0.05))


def test_smoothing_is_normalised_at_border(rng):
    t = rng.uniform(0, 1, (15, 17)).astype(np.float32)
    k = Kernel("box", 5)
    got = smooth_transmission(t, k)
    # corner pixel: mean of the 3x3 in-image part of its 5x5 window
    assert got[0, 0] == pytest.approx(t[:3, :3].mean(), rel=1e-5)
    assert got[7, 8] == pytest.approx(t[5:10, 6:11].mean(), rel=1e-5)


def test_guided_kernel_keeps_sky_fog_off_near_object():
    """Edge-aware option: a near dark object against the sky does not make a glow around it."""
    img = np.full((60, 60, 3), 230, np.uint8)
    img[20:40, 20:40] = 30
    dist = np.full((60, 60), np.inf, np.float32)
    dist[20:40, 20:40] = 5.0
    box = koschmieder_extended(img, dist, 0.1, kernel=Kernel("box", 19))
    guided = koschmieder_extended(img, dist, 0.1, kernel=Kernel("guided", 19, eps=1e-4))
    ref = koschmieder(img, dist, 0.1)
    halo = (slice(14, 20), slice(20, 40))  # sky just above the object
    assert np.abs(guided[halo].astype(int) - ref[halo]).mean() < np.abs(box[halo].astype(int) - ref[halo]).mean()


def test_fogger_levels_share_work_and_match_single_calls(rng):
    img = rng.integers(0, 256, (12, 14, 3), dtype=np.uint8)
    dist = rng.uniform(0, 100, (12, 14)).astype(np.float32)
    dist[0, :3] = np.inf  # sky
    f = Fogger(img, dist)
    first = {}
    for beta in (0.0, 0.03, 0.12):
        got = f(beta)
        ref = reference_standard(img, dist, beta, 255) if beta > 0 else img.astype(np.float64)
        assert got.dtype == np.uint8 and np.abs(got - ref).max() <= 0.5 + 1e-3, beta  # Eq. 2, correctly rounded
        assert np.array_equal(got, koschmieder(img, dist, beta))  # a fresh Fogger: no state from earlier calls
        first[beta] = got
    for beta in (0.12, 0.0, 0.03):  # again, in another order: nothing leaks between levels
        assert np.array_equal(f(beta), first[beta])
    assert np.array_equal(first[0.0], img) and (first[0.12][0, :3] == 255).all()
    assert np.all(np.diff([f(b).astype(int).sum() for b in (0.03, 0.06, 0.09)]) > 0)  # thicker = brighter


def test_transmission_values():
    d = np.array([[0.0, 10.0, np.inf]], np.float32)
    assert np.allclose(transmission(d, 0.1), [[1.0, math.exp(-1), 0.0]])
    assert np.allclose(transmission(d, 0.0), [[1.0, 1.0, 1.0]])


def test_density_field_mean_preserving_and_seeded():
    f1 = density_field((64, 96), np.random.default_rng(7), amplitude=0.4, scale_px=16)
    f2 = density_field((64, 96), np.random.default_rng(7), amplitude=0.4, scale_px=16)
    f3 = density_field((64, 96), np.random.default_rng(8), amplitude=0.4, scale_px=16)
    assert np.array_equal(f1, f2) and not np.array_equal(f1, f3)
    assert f1.mean() == pytest.approx(1.0, abs=1e-6)
    assert f1.min() >= 0.6 - 1e-6 and f1.max() <= 1.4 + 1e-6 and f1.std() > 0.05
    img = np.full((64, 96, 3), 50, np.uint8)
    dist = np.full((64, 96), 20.0, np.float32)
    patchy = koschmieder(img, dist, 0.05, density=f1)
    ref = reference_standard(img, dist * f1, 0.05, 255)
    assert np.abs(patchy - ref).max() <= 0.5 + 1e-3


def test_estimate_airlight_finds_the_haze():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 120, (100, 100, 3), dtype=np.uint8)
    img[:30, 60:] = (210, 220, 235)  # a bright hazy sky patch
    a = estimate_airlight(img)
    assert np.allclose(a, [210, 220, 235], atol=1)
    a16 = estimate_airlight(img.astype(np.uint16) * 257)
    assert np.allclose(a16, a, atol=1)  # always in 8-bit units


@pytest.mark.parametrize("bad, match", [
    (dict(beta=-0.1), "β"),
    (dict(beta=float("nan")), "β"),
    (dict(dist=np.full((4, 5), np.nan, np.float32)), "NaN"),
    (dict(dist=-np.ones((4, 5), np.float32)), "negative"),
    (dict(dist=np.ones((5, 4), np.float32)), "4×5"),
    (dict(airlight=300), "airlight"),
    (dict(space="lab"), "space"),
])
def test_bad_arguments_raise(bad, match):
    args = dict(image=np.zeros((4, 5, 3), np.uint8), dist=np.ones((4, 5), np.float32), beta=0.05,
                airlight=255, space="srgb") | bad
    with pytest.raises(ValueError, match=match):
        koschmieder(args["image"], args["dist"], args["beta"], args["airlight"], args["space"])


def test_kernel_validation():
    with pytest.raises(ValueError, match="odd"):
        Kernel("box", 4)
    with pytest.raises(ValueError, match="kernel must be"):
        Kernel("median", 5)
