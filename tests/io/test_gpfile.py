"""Labelled points: the biv-me GPFile and generic CSV / VTP readers, the labelled-domain config file, and labelled
files told from plain points (bitemesh.io on the data of ../shared/data/bivme_patient1).  The patient meshed:
tests/core/sources/test_bivme_patient.py."""
from __future__ import annotations

from pathlib import Path

import bitemesh
import numpy as np
import pytest
from bitemesh.core.errors import InvalidInputError
from bitemesh.io import read_labelled_points

#: the label counts of GPFile_000.txt (its SOURCE.md)
GPFILE_COUNTS = {"SAX_LV_ENDOCARDIAL": 233, "SAX_LV_EPICARDIAL": 216, "SAX_RV_FREEWALL": 186, "SAX_RV_SEPTUM": 87,
                 "SAX_RV_EPICARDIAL": 228, "LAX_LV_ENDOCARDIAL": 208, "LAX_LV_EPICARDIAL": 200,
                 "LAX_RV_FREEWALL": 130, "LAX_RV_SEPTUM": 70, "LAX_RV_EPICARDIAL": 233, "RV_INSERT": 10,
                 "MITRAL_VALVE": 6, "AORTA_VALVE": 2, "PULMONARY_VALVE": 2, "TRICUSPID_VALVE": 2, "APEX_POINT": 1}
PACKAGED = Path(bitemesh.__file__).resolve().parent / "data" / "bivme_patient1"


# --- reading ------------------------------------------------------------------------------------------------------

def test_the_gpfile_reads_with_its_label_counts_and_slices(gpfile):
    points, labels, slices = read_labelled_points(gpfile)
    assert points.shape == (1814, 3) and points.dtype == np.float64
    assert dict(zip(*np.unique(labels, return_counts=True))) == GPFILE_COUNTS
    assert sorted(np.unique(slices).tolist()) == [2, 3, 4, 5, 6, 7, 8, 9, 11]
    assert points[0].tolist() == [-42.09469, -25.37305, -29.46908] and labels[0] == "SAX_RV_FREEWALL"
    assert (points.min(axis=0) > [-75, -37, -114]).all() and (points.max(axis=0) < [58, 57, 7]).all()
    same_points, same_labels, _ = read_labelled_points(gpfile)
    assert np.array_equal(same_points, points) and np.array_equal(same_labels, labels)


def test_the_package_ships_the_gpfile_with_its_licence(gpfile, shared_data):
    assert (PACKAGED / "GPFile_000.txt").read_bytes() == gpfile.read_bytes()
    licence = shared_data / "bivme_patient1" / "LICENSE.biv-me"
    assert (PACKAGED / "LICENSE.biv-me").read_bytes() == licence.read_bytes()
    assert "Apache" in (PACKAGED / "SOURCE.md").read_text()


@pytest.mark.parametrize("separator", [",", ";", "\t", " "])
def test_a_csv_with_integer_labels_and_a_header_reads(tmp_path, separator):
    path = tmp_path / "contours.csv"
    rows = ["x y z label slice".replace(" ", separator), "1.5 2 3 1 7", "4 5 6 2 7", "7 8 9.25 2.0 8"]
    path.write_text("# exported contours\n" + "\n".join(row.replace(" ", separator) for row in rows) + "\n")
    points, labels, slices = read_labelled_points(path)
    assert points.tolist() == [[1.5, 2, 3], [4, 5, 6], [7, 8, 9.25]]
    assert labels.tolist() == ["1", "2", "2"] and slices.tolist() == [7, 7, 8]


def test_a_headerless_csv_with_string_labels_and_named_columns_in_any_order(tmp_path):
    path = tmp_path / "plain.txt"
    path.write_text("0 0 0 EPI\n1 0 0 LV_ENDO\n")
    points, labels, slices = read_labelled_points(path)
    assert labels.tolist() == ["EPI", "LV_ENDO"] and slices is None and points[1].tolist() == [1, 0, 0]
    path = tmp_path / "reordered.csv"
    path.write_text("Surface,Z,Y,X\nRV,3,2,1\n")
    points, labels, _ = read_labelled_points(path)
    assert points.tolist() == [[1, 2, 3]] and labels.tolist() == ["RV"]


@pytest.mark.parametrize("text, message", [
    ("x,y,z\n1,2,3\n", r"the header \['x', 'y', 'z'\] names no label column"),
    ("x,y,z,label\n1,2,3,EPI\n1,two,3,EPI\n", r"line 3 has the non-numeric coordinate 'two'"),
    ("x,y,z,label\n1,2,3,EPI\n1,2,3\n", r"line 3 has 3 columns but line 2 has 4"),
    ("1 2 3\n", r"line 1 has 3 fields; a labelled point needs x y z label \[slice\]"),
    ("x,y,z,label\n", r"the file has a header but no points"),
    ("x,y,z,label\n1,2,3, \n", r"1 points have an empty label"),
    ("x,y,z,label,slice\n1,2,3,A,first\n", r"line 2 has the non-numeric slice id 'first'"),
    ("x,y,z,label\n1,2,nan,A\n", r"NaN or infinite"),
])
def test_a_bad_labelled_table_says_which_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InvalidInputError, match=message):
        read_labelled_points(path)


def test_missing_empty_and_unknown_files_are_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="does not exist"):
        read_labelled_points(tmp_path / "absent.txt")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(InvalidInputError, match="the file is empty"):
        read_labelled_points(tmp_path / "empty.csv")
    (tmp_path / "points.xyz").write_text("1 2 3 A\n")
    with pytest.raises(InvalidInputError, match=r"unknown extension '.xyz'"):
        read_labelled_points(tmp_path / "points.xyz")


def write_vtp(path, points, arrays):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    data = vtkPolyData()
    vtk_points = vtkPoints()
    vtk_points.SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    data.SetPoints(vtk_points)
    for name, values in arrays.items():
        values = np.asarray(values)
        if values.dtype.kind == "U":
            array = vtkStringArray()
            for value in values:
                array.InsertNextValue(str(value))
        else:
            array = numpy_to_vtk(values, deep=True)
        array.SetName(name)
        data.GetPointData().AddArray(array)
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(data)
    assert writer.Write() == 1


@pytest.mark.parametrize("labels, expected", [
    (np.array([3, 1, 3], dtype=np.int32), ["3", "1", "3"]),
    (np.array(["EPI", "LV_ENDO", "EPI"]), ["EPI", "LV_ENDO", "EPI"]),
])
def test_a_vtp_with_a_label_array_reads(tmp_path, labels, expected):
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.5]])
    write_vtp(tmp_path / "labelled.vtp", points, {"Label": labels, "Slice": np.array([0, 0, 4], dtype=np.int64)})
    read, read_labels, slices = read_labelled_points(tmp_path / "labelled.vtp")
    assert np.array_equal(read, points) and read_labels.tolist() == expected and slices.tolist() == [0, 0, 4]


def test_a_vtp_without_a_label_array_names_its_arrays(tmp_path):
    write_vtp(tmp_path / "unlabelled.vtp", np.eye(3), {"Weight": np.array([1, 2, 3], dtype=np.int32)})
    with pytest.raises(InvalidInputError, match=r"no one-component point array named 'Label' \(point arrays "
                                                r"present: Weight\)"):
        read_labelled_points(tmp_path / "unlabelled.vtp")


# --- the config file ------------------------------------------------------------------------------------------------

def test_a_json_or_toml_config_gives_the_domain_settings(tmp_path):
    from bitemesh.io import read_labelled_config

    (tmp_path / "lv.json").write_text(
        '{"surfaces": {"EPI": ["SAX_LV_EPICARDIAL", "SAX_RV_SEPTUM"], "LV_ENDO": "SAX_LV_ENDOCARDIAL"}, '
        '"domain": "EPI - LV_ENDO", "base_plane": {"point": [0, 0, 1], "normal": [0, 0, 2]}, "min_wall": 2}')
    assert read_labelled_config(tmp_path / "lv.json") == {
        "surfaces": {"EPI": ["SAX_LV_EPICARDIAL", "SAX_RV_SEPTUM"], "LV_ENDO": ["SAX_LV_ENDOCARDIAL"]},
        "domain": "EPI - LV_ENDO", "base_plane": ([0, 0, 1], [0, 0, 2]), "min_wall": 2.0}
    (tmp_path / "heart.toml").write_text('domain = "EPI - LV_ENDO - RV_ENDO"\nbase_plane = "none"\n'
                                         'base_offset = -2.5\n[outlets]\nLV_ENDO = ["MITRAL_VALVE"]\n')
    assert read_labelled_config(tmp_path / "heart.toml") == {
        "domain": "EPI - LV_ENDO - RV_ENDO", "base_plane": None, "base_offset": -2.5,
        "outlets": {"LV_ENDO": ["MITRAL_VALVE"]}}
    (tmp_path / "fit.json").write_text('{"kernel": "cubic", "offset": 3, "smoothing": 0.1, "resolution": 0.8, '
                                       '"allow_implausible": 1}')
    assert read_labelled_config(tmp_path / "fit.json") == {"kernel": "cubic", "offset": 3.0, "smoothing": 0.1,
                                                          "resolution": 0.8, "allow_implausible": True}


@pytest.mark.parametrize("text, message", [
    ('{"domian": "EPI"}', r"unknown key\(s\) domian; known keys: domain, base_plane, min_wall"),
    ('{"min_wall": "thick"}', r"min_wall must be number, got 'thick'"),
    ('{"base_plane": [0, 0, 1]}', r"base_plane must be 'auto', 'valves', 'none', null or \{point"),
    ('{"surfaces": {"EPI": []}}', r"surfaces must be \{name: \[labels\]\}"),
    ('{"domain": "EPI"', r"cannot read a labelled-domain config from .*Expecting"),
    ('["EPI"]', r"must hold a table"),
    # the scalar keys are LabelledParameters' fields, checked by it (its ranges and choices)
    ('{"kernel": "gaussian"}', r"kernel must be one of .*linear"),
    ('{"offset": 0}', r"offset must be in \(0, inf\]"),
    ('{"rv_wall": 25}', r"rv_wall must be in \(0, 20\]"),
])
def test_a_bad_config_says_what_is_wrong(tmp_path, text, message):
    from bitemesh.io import read_labelled_config

    (tmp_path / "bad.json").write_text(text)
    with pytest.raises(InvalidInputError, match=message):
        read_labelled_config(tmp_path / "bad.json")


def test_labelled_files_are_told_from_plain_points(tmp_path, gpfile):
    from bitemesh.io import looks_labelled

    assert looks_labelled(gpfile)
    (tmp_path / "a.csv").write_text("x,y,z,label\n1,2,3,EPI\n")
    (tmp_path / "b.txt").write_text("1 2 3 4\n")          # x y nx ny: plain points
    (tmp_path / "c.txt").write_text("# c\n1 2 3 LV\n")
    (tmp_path / "d.csv").write_text("x,y,z,nx,ny,nz\n1,2,3,0,0,1\n")
    assert [looks_labelled(tmp_path / name) for name in ("a.csv", "b.txt", "c.txt", "d.csv")] == [True, False, True,
                                                                                                False]
    write_vtp(tmp_path / "l.vtp", np.eye(3), {"Label": np.array([1, 2, 2], dtype=np.int32)})
    write_vtp(tmp_path / "p.vtp", np.eye(3), {})
    assert looks_labelled(tmp_path / "l.vtp") and not looks_labelled(tmp_path / "p.vtp")
    assert not looks_labelled(tmp_path / "absent.csv") and not looks_labelled(tmp_path / "x.stl")
