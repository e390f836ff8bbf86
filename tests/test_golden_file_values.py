"""The strict loader refuses a golden file whose values are malformed, naming the array and its first bad row.

Independent of the writer: each file is built in the test with NumPy (``np.savez``), one defect at a
time on an otherwise well-formed case of three rows (tc_id 7, 8, 9; value_range [0, 5]): an expected
value NaN, infinite, or past the declared range; an array of the wrong shape; a truncated file. Each
raises InputError in one line naming the file, the array and the first offending row (with its tc_id).
"""

from __future__ import annotations

import hashlib
import io

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.golden import loader

META = {"file": "c.npz", "compare": ["y"], "inputs": {"x": {"dtype": "float32", "shape": [3]}},
        "outputs": {"y": {"dtype": "float32", "shape": [3]}}, "dtype": "float32", "metric": "abs",
        "exact": False, "count": 3, "value_range": [0, 5]}


def _blob(**over):
    a = {"x": np.zeros(3, np.float32), "y": np.array([0.5, 1.0, 2.0], np.float32),
         "y_tolerance_float32": np.full(3, 1e-6), "y_tolerance_float64": np.full(3, 1e-12),
         "category": np.array(["random", "stiff", "edge"]), "comment": np.array(["a", "b", "c"]),
         "result": np.array(["valid"] * 3), "tc_id": np.array([7, 8, 9], np.int32)}
    a.update(over)
    buf = io.BytesIO()
    np.savez(buf, **a)
    return buf.getvalue()


def _load(tmp_path, blob, meta=META):
    (tmp_path / "c.npz").write_bytes(blob)
    return loader.load_case_arrays(tmp_path, "c", dict(meta, sha256=hashlib.sha256(blob).hexdigest()))


@pytest.mark.parametrize("y, message", [
    ([0.5, np.nan, 1.0], r"y is not finite at row 1 \(tc_id 8\)$"),
    ([0.5, 1.0, -np.inf], r"y is not finite at row 2 \(tc_id 9\)$"),
    ([0.5, 5.5, -1.0], r"y is 5\.5, beyond the case's value_range \[0, 5\], at row 1 \(tc_id 8\)$"),
    ([-0.25, 1.0, 9.0], r"y is -0\.25, beyond the case's value_range \[0, 5\], at row 0 \(tc_id 7\)$"),
])
def test_an_expected_value_nan_infinite_or_past_the_range_is_refused_at_its_first_row(tmp_path, y, message):
    with pytest.raises(InputError, match=r"^golden file c\.npz: " + message) as e:
        _load(tmp_path, _blob(y=np.array(y, np.float32)))
    assert "\n" not in str(e.value)


def test_the_ends_of_the_range_are_inside_it_and_a_case_without_a_range_takes_any_finite_value(tmp_path):
    assert _load(tmp_path, _blob(y=np.array([0.0, 5.0, 2.5], np.float32)))["y"].tolist() == [0.0, 5.0, 2.5]
    free = dict(META, value_range=None)
    assert _load(tmp_path, _blob(y=np.array([-7.0, 1e30, 2.5], np.float32)), free)["y"][0] == -7.0


@pytest.mark.parametrize("over, message", [
    ({"y": np.zeros(4, np.float32)}, r"array 'y' has shape \(4,\), expected \(3,\)"),
    ({"y": np.zeros((3, 2), np.float32)}, r"array 'y' has shape \(3, 2\), expected \(3,\)"),
    ({"category": np.array(["random", "stiff"])}, r"array 'category' has shape \(2,\), expected 3 rows"),
    ({"y": np.zeros(3, np.float64)}, r"array 'y' expected dtype float32, found dtype float64"),
])
def test_an_array_of_the_wrong_shape_or_dtype_is_refused_naming_it(tmp_path, over, message):
    with pytest.raises(InputError, match=r"^golden file c\.npz: " + message):
        _load(tmp_path, _blob(**over))


@pytest.mark.parametrize("keep", [0.3, 0.6, 0.95])
def test_a_truncated_file_is_refused_in_one_line(tmp_path, keep):
    blob = _blob()
    with pytest.raises(InputError, match=r"^golden file c\.npz: ") as e:
        _load(tmp_path, blob[:int(len(blob) * keep)])
    assert "\n" not in str(e.value)


def test_a_sha256_wrong_in_its_last_digit_only_is_refused(tmp_path):
    # every one of the 64 digits counts: a manifest whose sha256 differs from the file's in the last digit alone
    blob = _blob()
    (tmp_path / "c.npz").write_bytes(blob)
    good = hashlib.sha256(blob).hexdigest()
    assert loader.load_case_arrays(tmp_path, "c", dict(META, sha256=good))["y"].tolist() == [0.5, 1.0, 2.0]
    for k in (63, 32, 16):
        bad = good[:k] + ("0" if good[k] != "0" else "1") + good[k + 1:]
        with pytest.raises(InputError, match=r"^golden: c\.npz does not match the sha256 in manifest\.json$"):
            loader.load_case_arrays(tmp_path, "c", dict(META, sha256=bad))


def test_a_case_read_alone_is_checked_against_its_manifest_entry_first(tmp_path):
    # load_case_arrays is public: its entry is checked before the file is opened (a file name outside the folder)
    (tmp_path / "g").mkdir()
    (tmp_path / "c.npz").write_bytes(_blob())
    meta = dict(META, file="../c.npz", sha256=hashlib.sha256(_blob()).hexdigest())
    with pytest.raises(InputError, match=r"expected a file name inside the golden folder, got '\.\./c\.npz'"):
        loader.load_case_arrays(tmp_path / "g", "c", meta)


def test_a_folder_marked_incomplete_is_refused_before_its_manifest_is_read(tmp_path):
    from moments_ref._io import INCOMPLETE

    (tmp_path / "manifest.json").write_text("{}")  # would be refused for its content; the marker comes first
    (tmp_path / INCOMPLETE).write_text("")
    with pytest.raises(InputError, match=r"^golden_dir: .* is incomplete: its writing was interrupted"):
        loader.load_manifest(tmp_path)


def test_an_archive_member_flagged_encrypted_is_refused_as_such(tmp_path):
    # zip general-purpose flag bit 0 (encryption) set on the member's local and central headers
    blob = bytearray(_blob())
    for sig, at in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
        i = blob.index(sig)
        blob[i + at] |= 0x1
    with pytest.raises(InputError, match=r"^golden file c\.npz: array '\w+' is encrypted \(zip flag bit 0\)"):
        _load(tmp_path, bytes(blob))
