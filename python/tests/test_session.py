"""lensblur.Session: a resident renderer whose renders equal the one-shot renders."""
import numpy as np
import pytest

import lensblur
from conftest import two_layer_stack

CAMERAS = [lensblur.Camera.physical(50, 2, 1.2), lensblur.Camera.physical(50, 2, 3), lensblur.Camera.physical(85, 1.4, 6)]
APERTURES = ["disk", "polygon:6"]


@pytest.mark.parametrize("flat", [False, True], ids=["layers", "flat RGB+Z"])
def test_a_sessions_renders_equal_one_shot_renders(flat):
    layers, depth = two_layer_stack(24, 32)
    if flat:  # one image and its depth: auto-layered, re-layered only when the camera moves
        layers, depth = np.ascontiguousarray(layers[1]), np.ascontiguousarray(depth[1])
    with lensblur.Session(layers, depth) as session:
        placed = set()
        for i, camera in enumerate(CAMERAS):
            for j, aperture in enumerate(APERTURES):
                image = session.render(camera, aperture=aperture)
                expected = lensblur.render(layers, depth, camera, aperture=aperture)
                assert np.abs(image - expected).max() <= 1e-5, (camera, aperture)
                stats = session.last_render
                # The method is prepared once where it runs: on a CPU device (lavapipe) a disk
                # renders this small frame on the CPU path, the hexagon always on the device.
                if aperture != "disk":
                    assert not stats["cpu"], stats
                assert stats["prepared"] == (stats["cpu"] not in placed), (i, j, stats)
                placed.add(stats["cpu"])
                # A new camera re-layers a flat image; another aperture never does.
                assert stats["relayered"] == (j == 0 and (flat or i == 0)), (i, j, stats)
        # Options and another method, as lensblur.render takes them.
        camera = CAMERAS[1]
        options = dict(near_blur=1.5, focus_at=(10, 12), method="gather")
        assert np.abs(session.render(camera, **options) - lensblur.render(layers, depth, camera, **options)).max() <= 1e-5
    with pytest.raises(lensblur.LensblurError, match="closed"):
        session.render(CAMERAS[0])


def test_a_session_refuses_bad_options_with_the_librarys_message_and_keeps_rendering():
    layers, depth = two_layer_stack(16, 16)
    session = lensblur.Session(layers, depth, method="drbokeh")
    with pytest.raises(lensblur.LensblurError, match="`samples` applies to `method`"):
        session.render(CAMERAS[0], samples=8)
    with pytest.raises(TypeError, match="unknown option 'fstop'"):
        session.render(CAMERAS[0], fstop=2)
    assert session.render(CAMERAS[0]).shape == (16, 16, 4)
    session.close()
    session.close()  # closing twice is harmless
