"""The window opens a CT file (NIfTI here) as it opens a DICOM folder: same volume, same path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging import load_series
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case
from tests.imaging.volume_writers import write_nifti, write_nrrd

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def test_a_nifti_file_opens_like_its_dicom_series(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    assert window.doc.path is not None
    dicom_stop = window.doc.path.result.stop_depth_mm
    series = load_series(phantom_case.ct_dir)
    nifti = write_nifti(tmp_path / "ct.nii.gz", series.hu, series.affine_lps)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(nifti)
    volume = window.doc.volume
    assert volume is not None and volume.info.source_format == "NIfTI-1"
    np.testing.assert_array_equal(volume.hu, series.hu)
    assert window.doc.path is not None
    assert window.doc.path.result.stop_depth_mm == pytest.approx(dicom_stop, abs=1e-6)


def test_a_dropped_volume_file_opens_itself(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    series = load_series(phantom_case.ct_dir)
    nrrd_file = write_nrrd(tmp_path / "dropped.nrrd", series.hu, series.affine_lps)
    with qtbot.waitSignal(window.doc.volume_changed, timeout=LOAD_TIMEOUT_MS):
        window.open_dropped(str(nrrd_file))
    assert window.doc.volume is not None and window.doc.volume.info.source_format == "NRRD"
