"""The numpy API: forward against the command line, files, errors with the library's messages."""
import subprocess
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import lensblur
from conftest import REPO, two_layer_stack


def test_forward_equals_the_command_lines_render_of_the_example(cli, example, tmp_path):
    # The README's render command on the example's layers, and the same render from Python.
    out = tmp_path / "cli.exr"
    subprocess.run(
        [cli, "render", str(example / "layers.exr"), "-o", str(out), "--focal-length", "50", "--fstop", "1.4", "--focus-distance", "3"],
        check=True,
        capture_output=True,
    )
    stack = lensblur.read_stack(example / "layers.exr")
    assert stack["layers"].shape[0] >= 2 and stack["depth_kind"] == "z"
    image = lensblur.render(stack["layers"], stack["depth"], lensblur.Camera.physical(50, 1.4, 3))
    expected = lensblur.read_image(out)
    assert image.shape == expected.shape == (192, 256, 4)
    # Same library: equal up to the float32 round trip of depth (1/(1/Z)) that read_stack's
    # planar-Z output adds, and, on a frame this small, the command line's CPU path against the
    # device (one-shot renders of small frames open none; measured 3.6e-7 apart).
    assert np.abs(image - expected).max() <= 1e-5


def test_the_header_camera_and_a_written_image_come_back(example, tmp_path):
    stack = lensblur.read_stack(example / "layers.exr")
    camera = stack["camera"]
    assert camera is not None and camera.is_physical and camera.focal_length_mm > 0
    image = lensblur.render(stack["layers"], stack["depth"], camera)
    lensblur.write_image(tmp_path / "out.exr", image)
    assert np.array_equal(lensblur.read_image(tmp_path / "out.exr"), image)


def test_a_single_image_is_split_into_layers_and_its_backward_is_refused():
    layers, depth = two_layer_stack(24, 32)
    flat, flat_depth = layers[1], depth[1]
    camera = lensblur.Camera.physical(50, 2, 3)
    image = lensblur.render(flat, flat_depth, camera)
    assert image.shape == (24, 32, 4) and np.isfinite(image).all()
    with pytest.raises(lensblur.LensblurError, match="gradients of an auto-layered image do not map onto its channels"):
        lensblur.render_backward(flat, flat_depth, camera, np.ones((24, 32, 3), np.float32))


def test_a_renderer_keeps_its_device_and_renders_every_method_it_is_asked_for():
    layers, depth = two_layer_stack(16, 16)
    r = lensblur.Renderer()
    assert r.device
    camera = lensblur.Camera.normalised(6.0, 0.5)
    for method in ("drbokeh", "gather"):
        assert r.render(layers, depth, camera, method=method, depth_kind="inverse-z").shape == (16, 16, 4)
    r.close()
    with pytest.raises(lensblur.LensblurError, match="closed"):
        r.render(layers, depth, camera)


def test_a_render_releases_the_gil_and_threads_sharing_a_renderer_queue():
    """While a render runs, other Python threads run: a ticker thread stamps the clock between
    the render's start and end (with the GIL held it could stamp nothing there, since stamping
    takes the GIL). Several threads rendering on one Renderer queue on its lock and each gets
    the result of a render alone."""
    r = lensblur.Renderer()
    camera = lensblur.Camera.physical(50, 1.4, 1.2)
    # A frame large enough that the render outlasts thread switches (0.1 s or more).
    for height, width in ((96, 128), (192, 256), (384, 512), (768, 1024)):
        layers, depth = two_layer_stack(height, width)
        expected = r.render(layers, depth, camera)  # also builds the pipelines
        start = time.perf_counter()
        r.render(layers, depth, camera)
        if time.perf_counter() - start >= 0.1:
            break
    stamps, done = [], threading.Event()

    def ticker():
        while not done.is_set():
            stamps.append(time.perf_counter())
            time.sleep(0.001)

    thread = threading.Thread(target=ticker)
    thread.start()
    time.sleep(0.02)
    start = time.perf_counter()
    image = r.render(layers, depth, camera)
    end = time.perf_counter()
    done.set()
    thread.join()
    during = [t for t in stamps if start < t < end]
    # Measured here: ~160 stamps in a 0.2 s render with the GIL released, 1 with it held (taken
    # between the clock read and the call).
    assert len(during) >= 10, f"{len(during)} stamps during a {end - start:.3f} s render of {width}x{height}"
    np.testing.assert_allclose(image, expected, atol=1e-6)

    with ThreadPoolExecutor(3) as pool:
        results = list(pool.map(lambda _: r.render(layers, depth, camera), range(3)))
    for result in results:
        np.testing.assert_allclose(result, expected, atol=1e-6)
    r.close()


@pytest.mark.parametrize(
    "change, error, message",
    [
        (lambda l, d, c: (np.ascontiguousarray(l[..., :3]), d, c), lensblur.LensblurError, r"layers must be premultiplied RGBA of shape \(L, H, W, 4\)"),
        (lambda l, d, c: (l, np.ascontiguousarray(d[:, :-1]), c), lensblur.LensblurError, r"depth must have shape \(2, 8, 10\) to match layers"),
        (lambda l, d, c: (l.astype(np.float64), d, c), TypeError, "layers must be float32, got float64"),
        (lambda l, d, c: (l[:, ::2], d[:, ::2], c), TypeError, "must be C-contiguous"),
        (lambda l, d, c: (np.where(np.arange(4) == 1, np.nan, l).astype(np.float32), d, c), lensblur.LensblurError, r"channel 'G' has 80 NaN/Inf sample\(s\)"),
        (lambda l, d, c: (l, -d, c), lensblur.LensblurError, "invalid depth"),
        (lambda l, d, c: (l, d, lensblur.Camera.normalised(1e6, 0.0)), lensblur.LensblurError, "larger than"),
    ],
)
def test_bad_input_raises_the_librarys_message(change, error, message):
    layers, depth = two_layer_stack(8, 10)
    layers, depth, camera = change(layers, depth, lensblur.Camera.physical(50, 2, 3))
    with pytest.raises(error, match=message):
        lensblur.render(layers, depth, camera)


def test_a_bad_camera_or_option_raises_the_librarys_message():
    with pytest.raises(lensblur.LensblurError, match="f-stop must be a positive number, got 0"):
        lensblur.Camera.physical(50, 0, 3)
    with pytest.raises(lensblur.LensblurError, match="blur K must be a non-negative number"):
        lensblur.Camera.normalised(-1, 0.5)
    layers, depth = two_layer_stack(8, 8)
    camera = lensblur.Camera.physical(50, 2, 3)
    with pytest.raises(lensblur.LensblurError, match="unknown depth kind 'metres'"):
        lensblur.render(layers, depth, camera, depth_kind="metres")
    with pytest.raises(lensblur.LensblurError, match="unknown method 'no-such-method'"):
        lensblur.render(layers, depth, camera, method="no-such-method")
    with pytest.raises(lensblur.LensblurError, match="has no backward pass"):
        lensblur.render_backward(layers, depth, camera, np.zeros((8, 8, 3), np.float32), method="gather")
    with pytest.raises(lensblur.LensblurError, match="alpha is not differentiated"):
        lensblur.render_backward(layers, depth, camera, np.ones((8, 8, 4), np.float32))
    with pytest.raises(lensblur.LensblurError, match="No such file|not found|layers.exr"):
        lensblur.read_stack("no/such/layers.exr")


def test_a_deep_file_is_refused_by_read_stack_pointing_at_what_reads_it():
    deep = REPO / "tests" / "data" / "openexr-deep" / "Balls.exr"
    with pytest.raises(lensblur.LensblurError, match=r"Balls\.exr: is a deep EXR, and this reader takes flat .* `lensblur render` reads deep files"):
        lensblur.read_stack(str(deep))
