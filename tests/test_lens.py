import math

import numpy as np
import pytest

from dofview.errors import DofviewError
from dofview.lens import Lens, PhysicalLens, exposure_from_ev, exposure_from_shutter


def thin_lens_coc_pixels(z, focus, focal, fnumber, fx):
    """Textbook thin-lens blur radius in pixels, derived independently of Eq. 3.

    An object at z images at v_z = f·z/(z − f); the sensor sits at v_f (focused at ``focus``); the
    blur circle on the sensor has diameter c = D·|v_z − v_f|/v_z with D = f/N. The pixel pitch is
    f/f_x (f_x is the focal length in pixels), so the radius in pixels is ½·c·f_x/f.
    """
    D = focal / fnumber
    v_f = focal * focus / (focus - focal)
    v_z = focal * z / (z - focal)
    c = D * abs(v_z - v_f) / v_z
    return 0.5 * c * fx / focal


@pytest.mark.parametrize("focus", [0.5, 2.0, 7.5])
@pytest.mark.parametrize("fnumber", [1.4, 2.8, 16.0])
def test_physical_lens_gives_the_same_coc_as_strength(focus, fnumber):
    fx = 1200.0
    phys = PhysicalLens(focal_mm=50.0, fnumber=fnumber, sensor_mm=36.0, units_per_metre=1.0)
    lens = phys.lens(fx, focus)
    f = phys.focal_units
    A = fx * (f / fnumber) * focus / (focus - f)  # Eq. 3 rearranged
    assert lens.aperture == pytest.approx(A, rel=1e-12)
    z = np.array([0.3, 1.0, 3.0, 20.0])
    expected = [thin_lens_coc_pixels(zi, focus, f, fnumber, fx) for zi in z]
    np.testing.assert_allclose(lens.coc_radius(z), expected, rtol=1e-9)


def test_coc_zero_on_focus_plane_and_grows_away():
    lens = Lens(focus=4.0, aperture=100.0)
    assert lens.coc_radius(4.0) == 0.0
    assert lens.coc_radius(2.0) == pytest.approx(0.5 * 100 * (0.5 - 0.25))
    assert lens.coc_radius(1e12) == pytest.approx(0.5 * 100 * 0.25)


def test_focus_at_infinity():
    lens = Lens(focus=math.inf, aperture=10.0)
    assert lens.coc_radius(5.0) == pytest.approx(1.0)
    assert PhysicalLens(50, 2).strength(1000.0, math.inf) == pytest.approx(1000.0 * 0.05 / 2)


def test_focus_at_focal_length_is_refused():
    with pytest.raises(DofviewError, match="beyond the focal length"):
        PhysicalLens(focal_mm=50, fnumber=2, units_per_metre=1.0).strength(1000.0, 0.05)


@pytest.mark.parametrize("kwargs", [dict(focus=0.0), dict(focus=-1.0), dict(focus=float("nan")),
                                    dict(focus=1.0, aperture=-1.0), dict(focus=1.0, aperture=float("inf"))])
def test_bad_lens_values(kwargs):
    with pytest.raises(DofviewError):
        Lens(**kwargs)


def test_exposure():
    assert exposure_from_ev(0) == 1.0
    assert exposure_from_ev(-2) == 0.25
    assert exposure_from_shutter(1 / 100, 2.0) == pytest.approx(1 / 400)
    with pytest.raises(DofviewError):
        exposure_from_ev(float("nan"))
    with pytest.raises(DofviewError):
        exposure_from_shutter(0.0, 2.0)
