"""``--device``: the CPU stays the default, ``cuda`` without CuPy or a GPU is one line and exit 2 before anything is
written, and a frame drawn by the device code (numpy as its namespace) is written in the CPU's formats with its
device in the sidecar."""

import json
import sys
import types

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.backends import check_device, device_method

RENDER = ["render", "macbeth_26", "--size", "120x80", "--illuminant", "D65", "--intensity", "1", "-q"]


def _fake_cupy(monkeypatch, count=None, error=None):
    """A stand-in ``cupy`` module whose runtime reports ``count`` GPUs or raises ``error``."""
    def get_count():
        if error is not None:
            raise error
        return count

    runtime = types.SimpleNamespace(getDeviceCount=get_count)
    module = types.ModuleType("cupy")
    module.cuda = types.SimpleNamespace(runtime=runtime)
    monkeypatch.setitem(sys.modules, "cupy", module)


def _run(argv, capsys):
    status = main(argv)
    return status, capsys.readouterr()


@pytest.mark.parametrize("setup, message", [
    (lambda mp: mp.setitem(sys.modules, "cupy", None), "--device cuda needs CuPy, which cannot be imported"),
    (lambda mp: _fake_cupy(mp, error=RuntimeError("cudaErrorNoDevice: no CUDA-capable device is detected")),
     "CuPy finds no usable NVIDIA GPU (cudaErrorNoDevice"),
    (lambda mp: _fake_cupy(mp, count=0), "CuPy finds no NVIDIA GPU"),
])
def test_cuda_without_cupy_or_gpu_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys, setup, message):
    setup(monkeypatch)
    out = tmp_path / "frames"
    status, captured = _run(RENDER + ["--device", "cuda", "--out", str(out)], capsys)
    assert status == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("camsim: error: ") and message in lines[0], captured.err
    assert not out.exists()


@pytest.mark.parametrize("extra, message", [
    (["--statistics", "paper"], "paper statistics render on the CPU only"),
    (["--method", "spectral"], "method spectral (per-wavelength-bin draws) renders on the CPU only"),
])
def test_cuda_refuses_what_a_device_does_not_draw(tmp_path, capsys, extra, message):
    status, captured = _run(RENDER + extra + ["--device", "cuda", "--out", str(tmp_path / "f")], capsys)
    assert status == 2 and message in captured.err and len(captured.err.strip().splitlines()) == 1


def test_unknown_device_is_a_usage_error(capsys):
    status, captured = _run(RENDER + ["--device", "tpu"], capsys)
    assert status == 2 and "invalid choice: 'tpu'" in captured.err


def test_device_checks():
    assert device_method("gaussian", "pixel") == "poisson" and device_method("table", "pixel") == "poisson"
    with pytest.raises(CamsimError, match="unknown sampling method"):
        device_method("fast", "pixel")
    with pytest.raises(CamsimError, match="unknown device"):
        check_device("tpu")
    check_device("cpu")
    check_device("numpy")


def test_cpu_sidecar_has_no_device_keys_and_the_device_code_writes_the_same_formats(tmp_path):
    """The default CPU frame's sidecar is as before (no device keys); the device code's frame (numpy namespace)
    has the same files and formats, its sidecar names the device and the method requested."""
    import rawpy

    import camsim
    from camsim.render.run import render_scene

    scene = camsim.load_scene("macbeth_26").replace(width=120, height=80, illuminants=("D65",),
                                                    intensity_factors=(0.5,), method="gaussian")
    cpu = render_scene(scene, tmp_path / "cpu", progress=False)
    dev = render_scene(scene, tmp_path / "dev", progress=False, device="numpy")
    files = cpu["frames"][0]["files"]
    assert files == dev["frames"][0]["files"]
    meta_cpu = json.loads((tmp_path / "cpu" / files["json"]).read_text())
    meta_dev = json.loads((tmp_path / "dev" / files["json"]).read_text())
    assert not {"device", "device_name", "device_library", "method_requested"} & set(meta_cpu)
    assert meta_dev["device"] == "numpy" and meta_dev["method"] == "poisson"
    assert meta_dev["method_requested"] == "gaussian" and meta_dev["device_library"].startswith("numpy ")
    assert set(meta_cpu) - {"auto_tolerance_ks"} <= set(meta_dev)
    frame = camsim.load_frame(tmp_path / "dev" / files["dng"])
    assert frame.pixels_dn.shape == (3, 80, 120) and frame.pixels_dn.dtype == np.uint8
    with rawpy.imread(str(tmp_path / "dev" / files["dng"])) as raw:
        assert np.array_equal(raw.raw_image[..., :3].transpose(2, 0, 1), frame.pixels_dn)
    from camsim.io.exr import read_exr

    noisy, clean, attributes = read_exr(tmp_path / "dev" / files["exr"])
    cpu_noisy, cpu_clean, cpu_attributes = read_exr(tmp_path / "cpu" / files["exr"])
    assert noisy.shape == cpu_noisy.shape and noisy.dtype == cpu_noisy.dtype
    np.testing.assert_array_equal(clean, cpu_clean)  # the same expectation, computed on the host either way
    assert set(attributes) == set(cpu_attributes)
