"""One line on standard error, and only camsim's (issue 24, point 7): a full disk under a Zarr dataset names the
file and leaves no ``resource_tracker: … leaked semaphore objects`` lines; a truncated PNG gives no ``libpng error:``
line of the library's own; numeric warnings do not reach the user."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from tests.support import clock
from tests.support.helpers import ROOT

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()


def _camsim(argv, tmp_path, pythonpath=()):
    """Run ``python -m camsim ARGV``; returns (exit status, stderr once every process it started is gone)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([*map(str, pythonpath), str(ROOT)])}
    err_path = tmp_path / "stderr.txt"
    with open(err_path, "w") as err:  # a file, not a pipe: what the resource tracker writes after the exit counts
        status = clock.run([sys.executable, "-m", "camsim", *argv], cpu_s=120, cwd=tmp_path, env=env, stderr=err,
                           stdout=subprocess.DEVNULL, wait_descendants=True).returncode
    return status, err_path.read_text()


@pytest.mark.slow
def test_zarr_full_disk_in_the_workers_is_one_line_naming_the_chunk(tmp_path):
    """Every chunk's flush fails with ENOSPC (in the pool's workers, through a ``sitecustomize`` that each process of
    the run imports): one line naming the chunk, exit 2, and the workers' semaphores (numcodecs' Blosc lock) are
    released, not reported leaked."""
    inject = tmp_path / "inject"
    inject.mkdir()
    (inject / "sitecustomize.py").write_text(textwrap.dedent("""\
        import errno, os
        from camsim.io import atomic
        _real = atomic.fsync_path
        def _full(path, *, directory=False):
            if not directory and "dataset.zarr" in str(path):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return _real(path, directory=directory)
        atomic.fsync_path = _full
        """))
    spec = tmp_path / "spec.toml"
    spec.write_text(f'name = "full"\nscene = "{SCENE}"\nseed = 1\n[frame]\nwidth = 64\nheight = 48\n'
                    '[grid]\nilluminants = ["D65", "A"]\n[random]\ncount = 3\n'
                    'intensity_factor = { uniform = [0.1, 1.0] }\n')
    out = tmp_path / "out"
    status, err = _camsim(["dataset", str(spec), "--out", str(out), "--format", "zarr", "--workers", "2", "-q"],
                          tmp_path, [inject])
    assert status == 2, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"camsim: error: cannot write {out / 'dataset.zarr'}") and "No space left" in err, err


@pytest.mark.slow
def test_a_truncated_png_is_one_line_without_libpngs_own(tmp_path):
    import numpy as np
    import OpenImageIO as oiio

    image = tmp_path / "whole.png"
    pixels = (np.random.default_rng(0).random((64, 64, 3)) * 255).astype(np.uint8)
    output = oiio.ImageOutput.create(str(image))
    output.open(str(image), oiio.ImageSpec(64, 64, 3, oiio.UINT8))
    output.write_image(pixels)
    output.close()
    data = image.read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    (tmp_path / "scene.toml").write_text('name = "cut"\n[image]\npath = "cut.png"\n')
    status, err = _camsim(["render", "scene.toml", "--out", "out", "-q"], tmp_path)
    assert status == 2, err
    assert len(err.splitlines()) == 1 and "libpng" not in err, err
    assert err.startswith(f"camsim: error: cannot read the pixels of image {tmp_path / 'cut.png'}: "), err
    assert "end of file" in err  # libpng's reason, in camsim's line


# --- numeric warnings: extreme values are refused with a reason, or computed without overflow -----------------

_CHART = 'name = "x"\n[chart]\n[light]\nilluminants = ["D65"]\nintensity_factors = [1.0]\n'


@pytest.mark.parametrize("extra, status, phrase", [
    ("[light]\nluminance_cd_m2 = 1e300\n", 2, "photon rates are not finite under this light"),  # photons.py
    ("[camera.scale]\nreference_exposure_s = 1e-308\n", 2, "overflows float64 at any F"),  # expected.py
    ("[sensor]\nconversion_gain_v_per_e = 1e-300\n", 2, "outside [1e-06, 1e+06] DN/e⁻"),
    ("[light]\nluminance_cd_m2 = 1e-308\n", 2, "too small for the EXR's linear sRGB view"),
    ("[sensor]\nread_noise_e = 1e30\n", 2, "read_noise_e must be ≥ 0 and ≤ 1e+08 e⁻"),  # beyond any full well
    ("[sensor]\ndsnu_e = 1e30\n", 2, "dsnu_e must be ≥ 0 and ≤ 1e+08 e⁻"),
    ("[sensor]\nread_noise_e = 1e8\n", 0, None),  # the largest σ: σ² = 1e16, in the normal draws (kernels.py)
    ("[sensor]\ndsnu_e = 1e8\n", 0, None),  # a correlation near 1 in the black level's bivariate normal
    ("[camera.scale]\nreference_electrons = 1e30\n", 0, None),  # the DNG colour matrix's responses (rawcolour.py)
    ("[camera.scale]\nreference_electrons = 1e308\n", 2, "reference_electrons must be at most 1e+30 e⁻"),
    ('[camera.scale]\nkind = "physical"\npixel_pitch_um = 1e150\n', 0, None),
])
def test_extreme_values_give_no_runtime_warning(tmp_path, capsys, extra, status, phrase):
    import warnings

    from camsim.cli import main
    from camsim.io.exr import read_exr

    text = _CHART.replace("[light]\n", "[light]\n" + extra.split("\n", 1)[1]) if extra.startswith("[light]") \
        else _CHART + extra
    scene = tmp_path / "x.toml"
    scene.write_text(text)
    out = tmp_path / "out"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["render", str(scene), "--size", "48x32", "--out", str(out), "-q"]) == status
    assert [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)] == []
    err = capsys.readouterr().err
    if status == 2:
        assert len(err.splitlines()) == 1 and phrase in err, err
    else:
        pixels, _, _ = read_exr(out / "x_D65_F1.exr")
        assert np.all(np.isfinite(pixels))


def test_normal_draws_with_a_sigma_whose_square_is_beyond_float32():
    from camsim.sensor.kernels import standard_normal_f32

    out, work = np.empty(100_000, np.float32), np.empty(50_000, np.float32)
    standard_normal_f32(np.random.default_rng(1), out, work, scale=1e30)
    assert np.all(np.isfinite(out)) and 0.98e30 < float(np.std(out.astype(np.float64))) < 1.02e30
    small = np.empty(10, np.float32)
    standard_normal_f32(np.random.default_rng(1), small, work, scale=2.0)
    reference = np.empty(10, np.float32)  # the folded path, unchanged: σ = 2 is the same draws times 2
    standard_normal_f32(np.random.default_rng(1), reference, work, scale=1.0)
    np.testing.assert_allclose(small, 2 * reference, rtol=1e-6)
