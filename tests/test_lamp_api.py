"""The lamp's public entry points: signatures, argument checks and the host/device contract for bad particles."""

import inspect

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_ball


@pytest.fixture(scope="module")
def ball():
    b = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    return b.centers, b.radii


def test_help_shows_every_option_with_its_default():
    """help(lamp_forces) lists its options and defaults (no **options), and lamp_update's and ShiningLamp's too."""
    for fn, names in (
        (wl.lamp_forces, ("cells_per_diameter", "criterion", "surfaces", "probe_radius", "walls", "tolerance")),
        (wl.lamp_update, ("cells_per_diameter", "criterion", "surfaces", "probe_radius", "walls")),
        (wl.ShiningLamp.__init__, ("criterion", "surfaces", "probe_radius", "walls", "tolerance")),
    ):
        params = inspect.signature(fn).parameters
        assert not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()), fn
        for name in names:
            assert params[name].kind is inspect.Parameter.KEYWORD_ONLY, (fn, name)
        assert params.get("cells_per_diameter", inspect.Parameter("x", 3, default=4)).default == 4
        for name in names:
            assert name in (fn.__doc__ or ""), (fn, name)


def test_a_misspelt_keyword_names_the_function_called(ball):
    """A misspelt keyword to lamp_forces is a TypeError naming lamp_forces, not an inner class the user never
    called."""
    c, r = ball
    with pytest.raises(TypeError, match=r"lamp_forces\(\) got an unexpected keyword argument 'cell_per_diameter'"):
        wl.lamp_forces(c, r, 1e6, cell_per_diameter=8)


@pytest.mark.parametrize("bad", ["0.1", True, None])
def test_probe_radius_of_the_wrong_type_is_refused_alike_everywhere(ball, bad):
    """ShiningLamp refuses a string or boolean probe radius as lamp_forces does (None: it is required)."""
    c, r = ball
    grid = wl.LampGrid.enclosing(c, r, probe_radius=0.003)
    err = ValueError if bad is None else TypeError
    with pytest.raises(err, match="probe_radius"):
        wl.ShiningLamp(grid, surfaces="all", probe_radius=bad, device="cpu")
    with pytest.raises(err, match="probe_radius"):
        wl.lamp_forces(c, r, 1e6, surfaces="all", probe_radius=bad, device="cpu")


def test_a_huge_probe_radius_is_blamed_on_the_probe(ball):
    """A probe so large that the default grid's margin breaks the budget is named as probe_radius, not as the
    cells or the grid."""
    c, r = ball
    with pytest.raises(ValueError, match=r"^probe_radius: 1000 m is .* mean particle diameters"):
        wl.lamp_forces(c, r, 1e6, surfaces="all", probe_radius=1e3, device="cpu")


def test_numpy_scalars_are_shown_as_numbers_in_messages():
    """Messages show 5, not np.int64(5)."""
    grid = wl.LampGrid([0, 0, 0], [1, 1, 1], 0.25)
    with pytest.raises(ValueError, match=r"criterion: .* got 5$"):
        wl.ShiningLamp(grid, criterion=np.int64(5), device="cpu")
    with pytest.raises(ValueError, match=r"depth_slots: .* got 9$"):
        wl.ShiningLamp(grid, criterion="area", depth_slots=np.int32(9), device="cpu")


def test_bad_particles_raise_on_the_host_and_are_counted_on_the_device(device, ball):
    """The documented contract: lamp_forces (host data) raises naming the first bad index; ShiningLamp (device
    arrays, capture-safe) skips the same particle and counts it, and the others get lamp_forces' forces."""
    c, r = ball
    bad = c.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"centers: non-finite value at index 3"):
        wl.lamp_forces(bad, r, 1e6, device=device)
    grid = wl.LampGrid.enclosing(c, r)
    lamp = wl.ShiningLamp(grid, device=device)
    lamp.update(*device_arrays(bad, r, device))
    assert lamp.diagnostics().invalid == 1
    keep = np.ones(len(r), dtype=bool)
    keep[3] = False
    expect = wl.lamp_forces(c, r, 1e6, grid=grid, active=keep, device=device)
    np.testing.assert_array_equal(lamp.forces_numpy(1e6), expect)


def test_a_wetted_lamp_on_no_particles_gives_no_forces(device):
    """N = 0 in the wetted mode works as in the others: no forces, nothing invalid (it raised inside Warp)."""
    grid = wl.LampGrid([0, 0, 0], [1, 1, 1], 0.1)
    lamp = wl.ShiningLamp(grid, surfaces="all", probe_radius=0.05, device=device)
    empty = wp.zeros(0, dtype=wp.vec3, device=device)
    lamp.update(empty, wp.zeros(0, dtype=wp.float32, device=device))
    assert lamp.forces_numpy(1e6).shape == (0, 3)
    out = wp.zeros(0, dtype=wp.vec3, device=device)
    lamp.add_forces(out, 1e6)
    f = wl.lamp_forces(np.zeros((0, 3)), np.zeros(0), 1e6, surfaces="all", probe_radius=0.05, device=device)
    assert f.shape == (0, 3)
