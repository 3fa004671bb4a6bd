"""MATLAB ``.mat`` loading: a damaged v5 file is an :class:`InputError` naming the file, the variable and the element,
never a crash of scipy's compiled reader."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from pdr.errors import InputError
from pdr.io import matfile
from tests.conftest import data_path

#: Inside a variable's miMATRIX element of the files written here: tag (8), array flags (16), dimensions (16), a
#: name of up to 4 characters in a small element (8); the data element's tag follows.
_DATA_TAG = 48


def _mat(tmp_path: Path, compress: bool) -> Path:
    p = tmp_path / "m.mat"
    savemat(p, {"acc": np.arange(12.0).reshape(4, 3), "s": {"txt": "hello", "c": np.array([1 + 2j])},
                "cel": np.array([np.arange(3.0), "abc"], dtype=object)}, do_compression=compress)
    return p


def _with_data_type(raw: bytes, mdtype: int) -> bytes:
    """``raw`` (a compressed file whose first variable is ``acc``) with the type code of its data element set."""
    size = struct.unpack_from("<I", raw, 132)[0]
    body = bytearray(zlib.decompress(raw[136:136 + size]))
    assert body[40:48] == struct.pack("<HH", 1, 3) + b"acc\0"  # the name, in a small element
    body[_DATA_TAG:_DATA_TAG + 4] = struct.pack("<I", mdtype)
    packed = zlib.compress(bytes(body))
    return raw[:128] + struct.pack("<II", 15, len(packed)) + packed + raw[136 + size:]


@pytest.mark.parametrize("compress", [False, True])
def test_intact_files_of_every_array_class_load(tmp_path, compress):
    p = _mat(tmp_path, compress)
    matfile.check_elements(p.read_bytes(), str(p))
    mat = matfile.load(p)
    np.testing.assert_array_equal(mat["acc"], np.arange(12.0).reshape(4, 3))
    assert mat["s"]["txt"][0, 0][0] == "hello"


@pytest.mark.parametrize("mdtype", [0, 8, 10, 11, 14, 15, 19, 20, 255])
def test_a_data_element_of_an_unknown_type_is_an_input_error_not_a_segfault(tmp_path, mdtype):
    """scipy 1.17 looks the type code up in a table of 20 slots unchecked: these codes crashed the interpreter with a
    segmentation fault (pdr inspect of such a copy of an IPIN trial ended with exit status 139)."""
    bad = tmp_path / "bad.mat"
    bad.write_bytes(_with_data_type(_mat(tmp_path, True).read_bytes(), mdtype))
    expected = (rf"not a readable MATLAB \.mat file \(damaged: element 1 at byte 128: a data element of unknown type "
                rf"{mdtype} .*, at byte 48 of its inflated data\)")
    with pytest.raises(InputError, match=expected) as e:
        matfile.load(bad)
    assert e.value.source == str(bad) and e.value.field == "acc"


def test_a_text_array_without_dimensions_is_refused(tmp_path):
    """A text array (in a struct field) whose dimensions element is empty crashed scipy as well."""
    raw = bytearray(_mat(tmp_path, False).read_bytes())
    dims = raw.index(b"txt\0") + 8 + 24  # the field's miMATRIX: tag, flags, then the dimensions' tag
    assert struct.unpack_from("<II", raw, dims) == (5, 8)
    raw[dims + 4:dims + 8] = bytes(4)
    with pytest.raises(InputError, match=r"array of 0 dimensions") as e:
        matfile.check_elements(bytes(raw), "m.mat")
    assert e.value.field == "s"


def test_sizes_beyond_the_file_and_bad_compressed_data_name_the_element(tmp_path):
    whole = _mat(tmp_path, True).read_bytes()
    with pytest.raises(InputError, match=r"element 1 at byte 128: an element declares \d+ bytes, 12 are left, at byte"):
        matfile.check_elements(whole[:148], "m.mat")
    flipped = bytearray(whole)
    flipped[140] ^= 0xFF
    with pytest.raises(InputError, match=r"element 1 at byte 128: its compressed data does not inflate"):
        matfile.check_elements(bytes(flipped), "m.mat")
    plain = bytearray(_mat(tmp_path, False).read_bytes())
    plain[132:136] = struct.pack("<I", 2**31)  # scipy read the first variable and silently dropped the others
    with pytest.raises(InputError, match=r"element 1 at byte 128: an element declares 2147483648 bytes"):
        matfile.check_elements(bytes(plain), "m.mat")


@pytest.mark.parametrize("raw", [b"MATLAB 5.0 MAT-file" + bytes(200), b"\x00" * 300,
                                 b"MATLAB 7.3 MAT-file" + bytes(105) + b"\x00\x02IM"])
def test_files_scipy_refuses_on_its_own_are_left_to_it(raw):
    matfile.check_elements(raw, "x.mat")  # version 0 of the header, a v4 file, a v7.3 (HDF5) file


@pytest.mark.data
def test_a_damaged_ipin_trial_is_an_error_naming_the_file_and_variable(tmp_path, capsys):
    from pdr.cli import main

    src = data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial53_repetition01.mat")
    raw = src.read_bytes()
    size = struct.unpack_from("<I", raw, 132)[0]
    body = bytearray(zlib.decompress(raw[136:136 + size]))
    body[_DATA_TAG:_DATA_TAG + 4] = struct.pack("<I", 8)   # the first variable, Posi: its data of type 8
    packed = zlib.compress(bytes(body))
    bad = tmp_path / "trial.mat"
    bad.write_bytes(raw[:128] + struct.pack("<II", 15, len(packed)) + packed + raw[136 + size:])
    assert main(["inspect", str(bad)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"error: {bad}, field 'Posi': not a readable MATLAB .mat file (damaged: "
                                        "element 1 at byte 128: a data element of unknown type 8")


def test_of_the_files_scipy_tests_its_reader_with_only_those_it_refuses_are_refused():
    """scipy's own test files (MATLAB v4-v7.2 of every array class, both byte orders, objects, function handles,
    opaque classes): the check refuses none that scipy reads (110 files with scipy 1.17, two refused: a bad zlib
    checksum and an element larger than the file)."""
    import io

    import scipy.io.matlab
    from scipy.io import loadmat

    files = sorted((Path(scipy.io.matlab.__file__).parent / "tests" / "data").glob("*.mat"))
    if not files:
        pytest.skip("scipy's test data is not installed")
    for f in files:
        raw = f.read_bytes()
        try:
            matfile.check_elements(raw, f.name)
        except InputError:
            with pytest.raises(Exception):  # noqa: B017, PT011 - scipy raises many types on corrupt input
                loadmat(io.BytesIO(raw))
