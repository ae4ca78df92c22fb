"""``--ct PATH``: one phantom as DICOM, NIfTI, NRRD and MetaImage, through every command.

The mandible phantom is written as a DICOM series at 0.5 mm (every geometry number exact in
binary floating point, float32 included: NIfTI stores its sform in float32) and its loaded
volume written again by nibabel, pynrrd and SimpleITK. The affines then agree bit for bit, so
the exports agree byte for byte: that is how byte identity is assured, and the test checks the
affines first so a failure says which side moved. A ToothFairy-style pair (a CBCT of grey values
and a nerve label map, both MetaImage) runs ``ctdrill export`` with no conversion.
"""

from __future__ import annotations

import contextlib
import csv
import io
import itertools
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging import load_ct, load_series
from ctdrill.imaging.phantom.io import write_phantom
from ctdrill.imaging.phantom.mandible import make_mandible_phantom
from tests.imaging.hostile_volumes import HOSTILE
from tests.imaging.volume_writers import write_mha, write_nifti, write_nrrd

FORMATS = ("dicom", "nifti", "nrrd", "metaimage")


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse usage errors
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def one_error_line(code: int, err: str) -> str:
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The phantom as DICOM, NIfTI, NRRD and MetaImage, and its plan."""
    root = tmp_path_factory.mktemp("ct-formats")
    phantom = make_mandible_phantom(spacing_mm=0.5, noise_hu=15.0, seed=7)
    written = write_phantom(root / "case", phantom)
    volume = load_series(written.ct_dir)
    assert np.array_equal(volume.affine_lps, volume.affine_lps.astype(np.float32))
    paths = {
        "dicom": written.ct_dir,
        "nifti": write_nifti(root / "ct.nii.gz", volume.hu, volume.affine_lps),
        "nrrd": write_nrrd(root / "ct.nrrd", volume.hu, volume.affine_lps),
        "metaimage": write_mha(root / "ct.mha", volume.hu, volume.affine_lps, compress=True),
    }
    return {
        "root": root,
        "paths": paths,
        "plan": written.plan_path,
        "phantom": phantom,
        "volume": volume,
    }


def test_four_formats_give_byte_identical_profiles_and_the_same_stop(case: dict[str, Any]) -> None:
    reference = case["volume"]
    outs = {}
    for fmt in FORMATS:
        volume = load_ct(case["paths"][fmt])
        np.testing.assert_array_equal(volume.hu, reference.hu)
        np.testing.assert_array_equal(volume.affine_lps, reference.affine_lps)  # bit for bit
        out = case["root"] / f"out-{fmt}"
        code, _, err = run_cli(
            [
                "export",
                "--ct",
                str(case["paths"][fmt]),
                "--plan",
                str(case["plan"]),
                "--out",
                str(out),
            ]
        )
        assert code == 0, err
        outs[fmt] = out
    profile = (outs["dicom"] / "profile.csv").read_bytes()
    force = (outs["dicom"] / "force.csv").read_bytes()
    stop = json.loads((outs["dicom"] / "summary.json").read_text())
    assert stop["stop_reason"] == "margin"
    for fmt in FORMATS[1:]:
        assert (outs[fmt] / "profile.csv").read_bytes() == profile, fmt
        assert (outs[fmt] / "force.csv").read_bytes() == force, fmt
        got = json.loads((outs[fmt] / "summary.json").read_text())
        for key in ("stop_depth_mm", "stop_reason", "max_safe_depth_mm", "min_clearance_mm"):
            assert got[key] == stop[key], (fmt, key)
    # --dicom is the same option as --ct
    code, _, err = run_cli(
        [
            "export",
            "--dicom",
            str(case["paths"]["nifti"]),
            "--plan",
            str(case["plan"]),
            "--out",
            str(case["root"] / "out-alias"),
        ]
    )
    assert code == 0, err
    assert (case["root"] / "out-alias" / "profile.csv").read_bytes() == profile


def _toothfairy_pair(case: dict[str, Any], folder: Path) -> tuple[Path, Path]:
    """A CBCT of unsigned grey values (HU + 1000) and a ToothFairy2-style label map (1 the
    mandible, 3 the left inferior alveolar canal, 4 a right one far away), both .mha (zlib)."""
    volume, phantom = case["volume"], case["phantom"]
    grey = np.clip(volume.hu.astype(np.int32) + 1000, 0, None).astype(np.uint16)
    labels = np.zeros(volume.hu.shape, dtype=np.uint8)
    labels[volume.hu > 300] = 1
    k, j, i = np.indices(volume.hu.shape)
    centres = volume.index_to_lps(np.stack([i, j, k], -1).reshape(-1, 3))
    line = np.asarray(phantom.canal_centerline_lps)
    reach = phantom.canal_radius_mm + 1.0
    near = np.flatnonzero(
        np.all((centres > line.min(0) - reach) & (centres < line.max(0) + reach), 1)
    )
    dist = np.full(near.size, np.inf)
    for a, b in itertools.pairwise(line):
        t = np.clip(((centres[near] - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
        dist = np.minimum(dist, np.linalg.norm(centres[near] - (a + t[:, None] * (b - a)), axis=1))
    labels.reshape(-1)[near[dist <= phantom.canal_radius_mm]] = 3
    labels[:3, :3, :3] = 4  # the other side's canal, nowhere near the drill
    cbct = write_mha(folder / "cbct.mha", grey, volume.affine_lps, compress=True)
    ian = write_mha(folder / "ian_labels.mha", labels, volume.affine_lps, compress=True)
    return cbct, ian


def test_toothfairy_style_mha_pair_runs_export_end_to_end(
    case: dict[str, Any], tmp_path: Path
) -> None:
    cbct, ian = _toothfairy_pair(case, tmp_path)
    doc = json.loads(case["plan"].read_text())
    doc.pop("series_uid_sha256", None)
    doc["landmarks"] = [{"name": "left IAN", "kind": "mask", "path": ian.name, "label": 3}]
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(doc))
    # grey values are not HU: refused until mapped, the refusal names the option
    code, _, err = run_cli(
        ["export", "--ct", str(cbct), "--plan", str(plan), "--out", str(tmp_path / "refused")]
    )
    assert "--grey-to-hu" in one_error_line(code, err)
    out = tmp_path / "out"
    code, stdout, err = run_cli(
        [
            "export",
            "--ct",
            str(cbct),
            "--plan",
            str(plan),
            "--grey-to-hu",
            "1,-1000",
            "--out",
            str(out),
        ]
    )
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] == "margin"
    # the nerve's voxels stand in for the analytic canal: the stop within a voxel of its own
    assert abs(summary["stop_depth_mm"] - case["phantom"].max_safe_depth_mm) <= 0.5
    rows = list(csv.DictReader((out / "profile.csv").open()))
    assert len(rows) > 100 and "grey-to-HU map" in stdout


def test_inspect_describes_a_file_as_a_dicom_series(case: dict[str, Any], tmp_path: Path) -> None:
    code, out, err = run_cli(["inspect", str(case["paths"]["dicom"]), "--json"])
    assert code == 0, err
    dicom = json.loads(out)
    for fmt in FORMATS[1:]:
        code, out, err = run_cli(["inspect", "--ct", str(case["paths"][fmt]), "--json"])
        assert code == 0, err
        doc = json.loads(out)
        assert doc.keys() == dicom.keys() and doc["info"].keys() == dicom["info"].keys()
        assert doc["dims"] == dicom["dims"] and doc["affine_lps"] == dicom["affine_lps"]
        assert doc["series"][0]["loaded"] and doc["series"][0]["slices"] == dicom["dims"][2]
        assert re.fullmatch(r"[0-9a-f]{64}", doc["series_uid"])
        assert doc["info"]["format"] in ("NIfTI-1", "NRRD", "MetaImage")
    one_error_line(*run_cli(["inspect", "--json"])[::2])
    code, out, err = run_cli(["inspect", "--ct", str(case["paths"]["nrrd"])])
    assert code == 0 and "NRRD file, content hash" in out


def test_header_text_reaches_outputs_only_with_include_phi(
    case: dict[str, Any], tmp_path: Path
) -> None:
    volume = case["volume"]
    nii = write_nifti(
        tmp_path / "named.nii", volume.hu, volume.affine_lps, descrip=b"DOE^JANE 1970"
    )
    nrrd_path = write_nrrd(
        tmp_path / "named.nrrd",
        volume.hu,
        volume.affine_lps,
        extra={"content": "JANE DOE", "patient_number": "PN-0042"},
    )
    for path, secret in ((nii, "DOE^JANE"), (nrrd_path, "JANE DOE")):
        _, out, _ = run_cli(["inspect", "--ct", str(path), "--json"])
        assert secret not in out and "PN-0042" not in out
        _, phi, _ = run_cli(["inspect", "--ct", str(path), "--json", "--include-phi"])
        assert secret in json.loads(phi)["info"]["series_description"]
        export = tmp_path / f"export-{path.suffix}"
        assert (
            run_cli(
                ["export", "--ct", str(path), "--plan", str(case["plan"]), "--out", str(export)]
            )[0]
            == 0
        )
        text = "".join(
            p.read_text(errors="replace") for p in export.iterdir() if p.suffix != ".png"
        )
        assert secret not in text and "PN-0042" not in text
        export_phi = tmp_path / f"phi-{path.suffix}"
        assert (
            run_cli(
                [
                    "export",
                    "--ct",
                    str(path),
                    "--plan",
                    str(case["plan"]),
                    "--out",
                    str(export_phi),
                    "--include-phi",
                ]
            )[0]
            == 0
        )
        assert (
            secret
            in json.loads((export_phi / "summary.json").read_text())["patient"]["description"]
        )


@pytest.mark.parametrize(
    "name", ["nifti_no_codes", "nrrd_spacing_1e300", "mha_matrix_x10", "nifti_4d", "mha_truncated"]
)
def test_hostile_headers_give_one_error_line(
    case: dict[str, Any], tmp_path: Path, name: str
) -> None:
    path, pattern = HOSTILE[name](tmp_path)
    err = one_error_line(*run_cli(["inspect", "--ct", str(path)])[::2])
    assert str(path) in err and re.search(pattern, err), err
    # the same file as a mask landmark of a plan
    doc = json.loads(case["plan"].read_text())
    doc["landmarks"] = [{"name": "canal", "kind": "mask", "path": str(path)}]
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(doc))
    code, _, err = run_cli(
        [
            "export",
            "--ct",
            str(case["paths"]["nifti"]),
            "--plan",
            str(plan),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert re.search(pattern, one_error_line(code, err)), err
    assert not (tmp_path / "out").exists()


def test_every_command_takes_a_ct_file(case: dict[str, Any], tmp_path: Path) -> None:
    nifti, plan = str(case["paths"]["nifti"]), str(case["plan"])
    code, _, err = run_cli(
        ["panorama", "--ct", nifti, "--plan", plan, "--out", str(tmp_path / "p")]
    )
    assert code == 0, err
    assert (tmp_path / "p" / "panorama.png").exists()
    code, _, err = run_cli(
        [
            "rehearse",
            "--ct",
            nifti,
            "--plan",
            plan,
            "--out",
            str(tmp_path / "r"),
            "--operator",
            "push:20",
            "--duration-s",
            "1",
        ]
    )
    assert code == 0, err
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["complete"] is True
    code, _, err = run_cli(
        ["report", "--ct", nifti, "--plan", plan, "--out", str(tmp_path / "r.pdf")]
    )
    assert code == 0, err
    assert (tmp_path / "r.pdf").stat().st_size > 0
    code, _, err = run_cli(
        ["suggest", "--ct", nifti, "--plan", plan, "--out", str(tmp_path / "s"), "--count", "12"]
    )
    assert code == 0, err
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"ct,plan\n{nifti},{plan}\n")
    code, _, err = run_cli(
        [
            "batch",
            str(manifest),
            "--out",
            str(tmp_path / "b"),
            "--workers",
            "1",
            "--no-plot",
            "--rate-hz",
            "100",
        ]
    )
    assert code == 0, err
    assert (tmp_path / "b" / "rows" / "0001" / "profile.csv").read_bytes() == (
        case["root"] / "out-dicom" / "profile.csv"
    ).read_bytes()
    manifest.write_text(f"ct,dicom,plan\n{nifti},{nifti},{plan}\n")
    assert "columns ct and dicom" in one_error_line(
        *run_cli(["batch", str(manifest), "--out", str(tmp_path / "b2")])[::2]
    )


def test_the_real_head_ct_exports_and_draws_its_panoramic(tmp_path: Path) -> None:
    """The VTK head CT (NIfTI) with tests/data/headsq_quarter.plan.json: a drill into the real
    mandible, and the panoramic along the arch fitted to it."""
    from tests.conftest import ROOT, SHARED_DATA

    head = str(SHARED_DATA / "vtk_headsq_quarter" / "headsq_quarter.nii.gz")
    plan = str(ROOT / "tests" / "data" / "headsq_quarter.plan.json")
    code, _, err = run_cli(["export", "--ct", head, "--plan", plan, "--out", str(tmp_path / "e")])
    assert code == 0, err
    summary = json.loads((tmp_path / "e" / "summary.json").read_text())
    assert summary["stop_reason"] == "planned_depth" and summary["stop_depth_mm"] == 12.0
    rows = list(csv.DictReader((tmp_path / "e" / "profile.csv").open()))
    bone = [float(r["hu"]) for r in rows if float(r["depth_mm"]) >= 2.0]
    assert min(bone) > 300.0  # in the mandible from 2 mm on
    code, _, err = run_cli(["panorama", "--ct", head, "--plan", plan, "--out", str(tmp_path / "p")])
    assert code == 0, err
    with np.load(tmp_path / "p" / "panorama.npz") as z:
        hu, lps = z["hu"], z["lps"]
    body = int(np.argmin(np.abs(lps[:, 0, 2] + 117.0)))  # the mandible's body, z = -117 mm
    assert (hu[body] > 300.0).mean() >= 0.95


def test_two_different_cts_are_refused_not_the_last_taken(tmp_path: Path) -> None:
    """``--dicom A --ct B``: the same option given two different CTs is one error line
    naming both, before anything is read; the same path twice is harmless."""
    demo = Path(__file__).resolve().parents[2] / "assets" / "demo"
    other = tmp_path / "other.nii"
    for cmd in ("export", "panorama"):
        code, _, err = run_cli(
            [
                cmd,
                *("--dicom", str(demo / "ct"), "--ct", str(other)),
                *("--plan", str(demo / "plan.json"), "--out", str(tmp_path / cmd)),
            ]
        )
        line = one_error_line(code, err)
        assert "the CT is already given" in line and str(other) in line and "demo" in line
        assert not (tmp_path / cmd).exists()
    code, _, err = run_cli(
        [
            "inspect",
            *("--ct", str(demo / "ct"), "--ct", str(demo / "ct")),
        ]
    )
    assert code == 0, err
    code, _, err = run_cli(["inspect", "--ct", str(demo / "ct"), "--ct", str(other)])
    assert "the CT is already given" in one_error_line(code, err)
