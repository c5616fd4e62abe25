"""Finding the cases (files, folders, glob patterns, a manifest), checking their options with the dataclasses of
``bitemesh mesh``, and the hash that says a case is up to date.  No Dask here."""
from __future__ import annotations

import pytest
from bitemesh.cohorts.cases import Case, case_hash, find_cases, read_manifest
from bitemesh.options import as_options, parse_option
from bitemesh.core.errors import InvalidInputError

from tests.cohorts.conftest import write_manifest


def test_files_folders_and_patterns_give_one_case_each(inputs, tmp_path):
    folder = inputs["sphere"].parent
    by_folder = find_cases([folder])
    assert [case.name for case in by_folder] == sorted(case.name for case in by_folder)
    assert {case.name for case in by_folder} >= {"sphere", "annulus", "ball", "broken"}
    assert {case.output_name for case in find_cases([str(folder / "*.xyz")], ".msh")} >= \
        {"sphere.msh", "annulus.msh", "broken.msh"}
    [ball] = find_cases([inputs["ball"]])
    assert (ball.name, ball.input, ball.options) == ("ball", inputs["ball"], {})
    with pytest.raises(InvalidInputError, match="two cases would write sphere.vtu"):
        find_cases([inputs["sphere"], folder])
    with pytest.raises(InvalidInputError, match="does not exist"):
        find_cases([tmp_path / "absent.xyz"])
    with pytest.raises(InvalidInputError, match=r"\.stl.*\.vtu"):
        find_cases([inputs["sphere"]], ".stl")


def test_a_manifest_gives_names_formats_and_checked_options(inputs, tmp_path):
    manifest = write_manifest(tmp_path / "cases.csv", [
        (inputs["sphere"], "coarse", 800, "auto", ""),
        (inputs["sphere"], "fine.msh", 3000, 0.05, 2),
        (inputs["ball"], "", "", "", "1;3")], header=("input", "output", "cells", "grid-spacing", "label"))
    coarse, fine, ball = find_cases([manifest])
    assert (coarse.output_name, coarse.options) == ("coarse.vtu", {"cells": 800, "grid_spacing": None})
    assert (fine.output_name, fine.options) == ("fine.msh", {"cells": 3000, "grid_spacing": 0.05, "label": (2,)})
    assert (ball.name, ball.options) == ("ball", {"label": (1, 3)})


@pytest.mark.parametrize("header, cells, words", [
    (("input", "radus"), ("0.2",), ["radus", "did you mean radius (--radius)"]),
    (("input", "cells"), ("5",), ["line 2", "cells", "5", r"[100"]),
    (("input", "grid_spacing"), ("fine",), ["line 2", "grid_spacing", "number", "fine"]),
    (("input", "method"), ("voronoi",), ["line 2", "method", "voronoi", "mpu"]),
])
def test_a_bad_manifest_is_refused_naming_the_column_and_the_value(header, cells, words, inputs, tmp_path):
    manifest = write_manifest(tmp_path / "bad.csv", [(inputs["sphere"], *cells)], header=header)
    with pytest.raises(InvalidInputError) as error:
        read_manifest(manifest)
    for word in words:
        assert word in str(error.value), (word, str(error.value))


def test_options_are_those_of_bitemesh_mesh():
    assert as_options({"cells": 2000}).cells == 2000 and as_options({}).optimize == 1
    assert as_options({"label": 3}).label == (3,)
    with pytest.raises(InvalidInputError, match="did you mean grid_spacing"):
        as_options({"grid_spacings": 0.1})
    with pytest.raises(InvalidInputError, match="radius"):
        as_options({"radius": -2})
    assert parse_option("radius", "-1") is None and parse_option("radius", "auto") is None
    assert parse_option("seed", "7") == 7 and parse_option("threshold", "0.3") == 0.3
    assert parse_option("ras", "1") is True and parse_option("domain", " EPI - LV_ENDO ") == "EPI - LV_ENDO"


def test_the_hash_follows_the_input_and_the_options(inputs, tmp_path):
    copy = tmp_path / "sphere.xyz"
    copy.write_bytes(inputs["sphere"].read_bytes())
    case = Case("sphere", copy)
    first = case_hash(case, {"cells": 1500})
    assert case_hash(case, {"cells": 1500}) == first
    assert case_hash(Case("sphere", copy, {"cells": 1500}), {}) == first       # the case's own option, same value
    assert case_hash(case, {"cells": 1500, "seed": 0}) == first                # a default given is the default
    assert case_hash(case, {"cells": 1500, "threads": 1}) == first             # how it runs, not what it makes
    assert case_hash(case, {"cells": 1600}) != first
    assert case_hash(Case("sphere", copy, extension=".msh"), {"cells": 1500}) != first
    copy.write_bytes(copy.read_bytes() + b"\n0 0 1 0 0 1\n")
    assert case_hash(case, {"cells": 1500}) != first

