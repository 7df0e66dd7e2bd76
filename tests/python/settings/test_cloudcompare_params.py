"""Tests for m3c2kit.cloudcompare_params: reading CloudCompare qM3C2 parameter files."""

import os
import re

import pytest

from m3c2kit.settings.cloudcompare_params import read_cloudcompare_params
from m3c2kit.base.errors import UsageError

# The parameter file behind /work/shared/data/pairs/autzen-bmx/autzen-bmx-cc.txt, in the key
# order qM3C2 writes.  The multi-scale keys are unused (NormalMode=0) and hold the values qM3C2's
# guess would put there (D/2, D/2, 2D).
AUTZEN_BMX = """\
[General]
M3C2VER=1
NormalScale=2.780864
NormalMode=0
NormalMinScale=1.390432
NormalStep=1.390432
NormalMaxScale=5.561728
NormalUseCorePoints=false
NormalPreferedOri=4
SearchScale=5.780864
SearchDepth=5.5
SubsampleRadius=1.390432
SubsampleEnabled=false
RegistrationError=0
RegistrationErrorEnabled=false
UseSinglePass4Depth=true
PositiveSearchOnly=false
UseMedian=false
UseMinPoints4Stat=false
MinPoints4Stat=5
ProjDestIndex=2
UseOriginalCloud=false
ExportStdDevInfo=true
ExportDensityAtProjScale=true
MaxThreadCount=8
UsePrecisionMaps=false
PM1Scale=1
PM2Scale=1
"""

AUTZEN_BMX_OPTIONS = {
    "normal_source": "reference",
    "normal_scale": 2.780864,
    "orient": "+z",
    "projection_scale": 5.780864,
    "max_depth": 5.5,
    "registration_error": 0.0,
    "median": False,
    "min_points": 5,
    "core_spacing": None,
    "depth_search": "single",
    "positive_search_only": False,
    "threads": 8,
    "position": "core",
    "compat": "cloudcompare",
}

MINIMAL = {"M3C2VER": "1", "NormalScale": "2", "SearchScale": "1", "SearchDepth": "3"}


def write(tmp_path, text, name="params.txt", newline="\n"):
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode())
    return path


def write_keys(tmp_path, keys=None, drop=(), **changes):
    entries = dict(MINIMAL if keys is None else keys)
    entries.update(changes)
    for key in drop:
        entries.pop(key)
    body = "".join(f"{k}={v}\n" for k, v in entries.items())
    return write(tmp_path, "[General]\n" + body)


def read(tmp_path, **changes):
    return read_cloudcompare_params(write_keys(tmp_path, **changes))


def rejects(tmp_path, fragment, text=None, **changes):
    """Assert the file is rejected with a message naming the file and containing `fragment`."""
    path = write(tmp_path, text) if text is not None else write_keys(tmp_path, **changes)
    with pytest.raises(UsageError, match=re.escape(fragment)) as info:
        read_cloudcompare_params(path)
    assert str(info.value).startswith(f"{path}: ")
    return str(info.value)


# --- the autzen-bmx file ------------------------------------------------------------------------


def test_autzen_bmx_file_maps_to_expected_options(tmp_path):
    assert read_cloudcompare_params(write(tmp_path, AUTZEN_BMX)) == AUTZEN_BMX_OPTIONS


def test_autzen_bmx_file_accepts_str_and_pathlike(tmp_path):
    path = write(tmp_path, AUTZEN_BMX)
    assert read_cloudcompare_params(str(path)) == read_cloudcompare_params(path)


def test_minimal_file_gets_qm3c2_factory_defaults(tmp_path):
    assert read(tmp_path) == {
        "normal_source": "reference",
        "normal_scale": 2.0,
        "orient": "+z",
        "projection_scale": 1.0,
        "max_depth": 3.0,
        "registration_error": 0.0,
        "median": False,
        "min_points": 5,
        "core_spacing": None,
        "depth_search": "progressive",
        "positive_search_only": False,
        "position": "compared",
        "compat": "cloudcompare",
    }


# --- key-by-key mapping -------------------------------------------------------------------------


def test_scales_are_diameters_and_depth_is_a_half_length_unchanged(tmp_path):
    opts = read(tmp_path, NormalScale="0.25", SearchScale="1.5e-1", SearchDepth="+7")
    assert (opts["normal_scale"], opts["projection_scale"], opts["max_depth"]) == (0.25, 0.15, 7.0)


def test_normal_mode_0_computes_on_reference(tmp_path):
    opts = read(tmp_path, NormalMode="0")
    assert opts["normal_source"] == "reference" and opts["normal_scale"] == 2.0


def test_normal_mode_3_is_vertical_and_needs_no_scale_or_orientation(tmp_path):
    opts = read(tmp_path, NormalMode="3", NormalPreferedOri="5", drop=["NormalScale"])
    assert opts["normal_source"] == "vertical"
    assert "normal_scale" not in opts and "orient" not in opts


def test_normal_mode_4_is_horizontal_with_scale_and_orientation(tmp_path):
    opts = read(tmp_path, NormalMode="4", NormalScale="1.5", NormalPreferedOri="0")
    assert opts["normal_source"] == "horizontal"
    assert (opts["normal_scale"], opts["orient"]) == (1.5, "+x")


def test_normal_mode_4_requires_normal_scale(tmp_path):
    rejects(tmp_path, "missing NormalScale", NormalMode="4", drop=["NormalScale"])


def test_normal_mode_5_uses_core_normals_as_they_are(tmp_path):
    # qM3C2 neither re-orients core-point normals nor fits them, so the orientation and the
    # core-points neighbourhood flag have no effect there, whatever their value.
    opts = read(tmp_path, NormalMode="5", NormalPreferedOri="10", NormalUseCorePoints="true",
                drop=["NormalScale"])
    assert opts["normal_source"] == "core"
    assert "normal_scale" not in opts and "orient" not in opts


def test_normal_mode_1_is_rejected(tmp_path):
    message = rejects(
        tmp_path,
        "NormalMode=1 (normals stored in the reference cloud) is not supported",
        NormalMode="1",
    )
    assert "NormalMode=5" in message


@pytest.mark.parametrize("mode", ["6", "-1"])
def test_unknown_normal_mode_is_rejected(tmp_path, mode):
    rejects(tmp_path, f"NormalMode={mode} is not a CloudCompare normal mode", NormalMode=mode)


@pytest.mark.parametrize(
    "ori, orient",
    [("0", "+x"), ("1", "-x"), ("2", "+y"), ("3", "-y"), ("4", "+z"), ("5", "-z"),
     ("6", "away:barycentre"), ("7", "barycentre"), ("8", "away:origin"), ("9", "origin"),
     ("11", "away:sensor"), ("12", "sensor")],
)
def test_preferred_orientation(tmp_path, ori, orient):
    assert read(tmp_path, NormalPreferedOri=ori)["orient"] == orient


@pytest.mark.parametrize("ori", ["10"])
@pytest.mark.parametrize("mode", ["0", "2", "4"])
def test_unsupported_preferred_orientation_is_rejected(tmp_path, ori, mode):
    message = rejects(
        tmp_path,
        f"NormalPreferedOri={ori} (",
        NormalPreferedOri=ori,
        NormalMode=mode,
        NormalMinScale="1",
        NormalStep="1",
        NormalMaxScale="2",
    )
    assert "is not supported" in message
    assert "--orient" in message and "barycentre" in message


@pytest.mark.parametrize("ori", ["13", "-1", "255"])
def test_invalid_preferred_orientation_is_rejected(tmp_path, ori):
    rejects(tmp_path, f"NormalPreferedOri={ori} is not a CloudCompare orientation",
            NormalPreferedOri=ori)


def test_normal_use_core_points(tmp_path):
    assert read(tmp_path, NormalUseCorePoints="false") == read(tmp_path)
    rejects(tmp_path, "NormalUseCorePoints=true", NormalUseCorePoints="true")
    rejects(tmp_path, "NormalUseCorePoints=true", NormalUseCorePoints="true", NormalMode="4")


@pytest.mark.parametrize("enabled, expected", [("true", 0.05), ("false", 0.0)])
def test_registration_error(tmp_path, enabled, expected):
    opts = read(tmp_path, RegistrationErrorEnabled=enabled, RegistrationError="0.05")
    assert opts["registration_error"] == expected


def test_registration_error_zero_is_allowed(tmp_path):
    opts = read(tmp_path, RegistrationErrorEnabled="true", RegistrationError="0")
    assert opts["registration_error"] == 0.0


@pytest.mark.parametrize("flag, expected", [("true", True), ("false", False)])
def test_use_median(tmp_path, flag, expected):
    assert read(tmp_path, UseMedian=flag)["median"] is expected


@pytest.mark.parametrize("flag, expected", [("true", 12), ("false", 5)])
def test_min_points(tmp_path, flag, expected):
    assert read(tmp_path, UseMinPoints4Stat=flag, MinPoints4Stat="12")["min_points"] == expected


def test_min_points_flag_off_needs_no_count(tmp_path):
    assert read(tmp_path, UseMinPoints4Stat="false")["min_points"] == 5


@pytest.mark.parametrize("flag, expected", [("true", 0.4), ("false", None)])
def test_subsample(tmp_path, flag, expected):
    assert read(tmp_path, SubsampleEnabled=flag, SubsampleRadius="0.4")["core_spacing"] == expected


def test_subsample_radius_unused_when_disabled_may_be_zero(tmp_path):
    assert read(tmp_path, SubsampleEnabled="false", SubsampleRadius="0")["core_spacing"] is None


@pytest.mark.parametrize("flag, expected", [("true", "single"), ("false", "progressive")])
def test_depth_search(tmp_path, flag, expected):
    assert read(tmp_path, UseSinglePass4Depth=flag)["depth_search"] == expected


@pytest.mark.parametrize("flag, expected", [("true", True), ("false", False)])
def test_positive_search_only(tmp_path, flag, expected):
    assert read(tmp_path, PositiveSearchOnly=flag)["positive_search_only"] is expected


@pytest.mark.parametrize("count, expected", [("0", 1), ("1", 1), ("8", 8), ("64", 64)])
def test_max_thread_count(tmp_path, count, expected):
    assert read(tmp_path, MaxThreadCount=count)["threads"] == expected


def test_max_thread_count_absent_leaves_threads_to_the_caller(tmp_path):
    assert "threads" not in read(tmp_path)


@pytest.mark.parametrize("index, dest", [("0", "reference"), ("1", "compared"), ("2", "core")])
def test_proj_dest_index(tmp_path, index, dest):
    assert read(tmp_path, ProjDestIndex=index)["position"] == dest


def test_precision_maps_off_accepts_and_ignores_pm_scales(tmp_path):
    opts = read(tmp_path, UsePrecisionMaps="false", PM1Scale="0.001", PM2Scale="1000")
    assert opts == read(tmp_path)


def test_precision_maps_on_selects_m3c2_pm_with_its_scales(tmp_path):
    """UsePrecisionMaps=true is M3C2-PM (issue 16); PM1Scale / PM2Scale the clouds' scales."""
    opts = read(tmp_path, UsePrecisionMaps="true", PM1Scale="0.5", PM2Scale="2")
    assert opts["uncertainty"] == "pm" and opts["precision_scales"] == [0.5, 2.0]
    assert "PM1Scale" in rejects(tmp_path, "PM1Scale", UsePrecisionMaps="true", PM1Scale="0", PM2Scale="1")


@pytest.mark.parametrize(
    "key", ["UseOriginalCloud", "ExportStdDevInfo", "ExportDensityAtProjScale"]
)
@pytest.mark.parametrize("flag", ["true", "false"])
def test_output_only_keys_change_nothing(tmp_path, key, flag):
    assert read(tmp_path, **{key: flag}) == read(tmp_path)


@pytest.mark.parametrize(
    "text, expected", [("TRUE", True), ("False", False), ("1", True), ("0", False)]
)
def test_boolean_spellings_qvariant_accepts(tmp_path, text, expected):
    assert read(tmp_path, UseMedian=text)["median"] is expected


def test_compat_options_are_implied_by_compat_not_emitted(tmp_path):
    """The file's settings carry compat="cloudcompare" (so the API and --params read it alike); the
    options it implies are not repeated."""
    opts = read_cloudcompare_params(write(tmp_path, AUTZEN_BMX))
    assert "variance" not in opts and "scale_selection" not in opts and opts["compat"] == "cloudcompare"


# --- multi-scale normals ------------------------------------------------------------------------


def multi(tmp_path, low, step, high):
    opts = read(tmp_path, NormalMode="2", NormalMinScale=low, NormalStep=step, NormalMaxScale=high,
                drop=["NormalScale"])
    assert opts["normal_source"] == "reference" and opts["orient"] == "+z"
    return opts["normal_scale"]


def accumulated(low, step, high):
    """The scales qM3C2 itself generates: for (s = low; s <= high; s += step)."""
    scales, s = [], low
    while s <= high:
        scales.append(s)
        s += step
    return scales


def test_multi_scale_keeps_largest_scale_that_accumulation_drops(tmp_path):
    assert len(accumulated(0.1, 0.1, 0.3)) == 2  # the case the slack exists for
    scales = multi(tmp_path, "0.1", "0.1", "0.3")
    assert scales == pytest.approx([0.1, 0.2, 0.3], rel=1e-15)
    assert scales == [0.1 + k * 0.1 for k in range(3)]


def test_multi_scale_even_steps(tmp_path):
    assert multi(tmp_path, "0.5", "0.5", "2.5") == [0.5, 1.0, 1.5, 2.0, 2.5]


def test_multi_scale_step_not_reaching_max(tmp_path):
    assert multi(tmp_path, "1", "0.4", "2") == pytest.approx([1.0, 1.4, 1.8], rel=1e-15)


def test_multi_scale_min_equal_max_gives_one_scale(tmp_path):
    assert multi(tmp_path, "3", "1", "3") == [3.0]


def test_multi_scale_many_fine_steps(tmp_path):
    scales = multi(tmp_path, "0.01", "0.01", "1")
    assert len(scales) == 100 and scales[-1] == pytest.approx(1.0)


def test_multi_scale_slack_is_relative_and_tiny(tmp_path):
    assert multi(tmp_path, "1", "1", "2.999999") == [1.0, 2.0]


def test_multi_scale_ignores_normal_scale_value(tmp_path):
    opts = read(tmp_path, NormalMode="2", NormalMinScale="1", NormalStep="1", NormalMaxScale="2",
                NormalScale="0")
    assert opts["normal_scale"] == [1.0, 2.0]


def test_multi_scale_rejects_max_below_min(tmp_path):
    rejects(tmp_path, "NormalMinScale/NormalStep/NormalMaxScale: the largest scale 1.0 is below the smallest 2.0", NormalMode="2",
            NormalMinScale="2", NormalStep="1", NormalMaxScale="1")


@pytest.mark.parametrize("key", ["NormalMinScale", "NormalStep", "NormalMaxScale"])
def test_multi_scale_rejects_non_positive(tmp_path, key):
    keys = {"NormalMinScale": "1", "NormalStep": "1", "NormalMaxScale": "2", key: "0"}
    rejects(tmp_path, f"{key}=0.0 must be > 0", NormalMode="2", **keys)


@pytest.mark.parametrize("key", ["NormalMinScale", "NormalStep", "NormalMaxScale"])
def test_multi_scale_requires_its_keys(tmp_path, key):
    keys = {"NormalMinScale": "1", "NormalStep": "1", "NormalMaxScale": "2"}
    del keys[key]
    rejects(tmp_path, f"missing {key}", NormalMode="2", **keys)


def test_multi_scale_rejects_absurd_scale_count(tmp_path):
    rejects(tmp_path, "step 1e-12 gives", NormalMode="2", NormalMinScale="1",
            NormalStep="1e-12", NormalMaxScale="2")


# --- rejections ---------------------------------------------------------------------------------


def test_unknown_key_is_rejected(tmp_path):
    rejects(tmp_path, "unknown CloudCompare parameter 'Foo'", Foo="1")


@pytest.mark.parametrize(
    "wrong, right",
    [
        ("normalscale", "NormalScale"),
        ("SEARCHDEPTH", "SearchDepth"),
        ("m3c2ver", "M3C2VER"),
        ("NormalPreferredOri", None),
    ],
)
def test_key_with_wrong_case_names_expected_spelling(tmp_path, wrong, right):
    if right is None:  # a different spelling, not just a different case
        rejects(tmp_path, f"unknown CloudCompare parameter '{wrong}'", **{wrong: "4"})
    else:
        rejects(tmp_path, f"'{wrong}' must be spelled '{right}'", **{wrong: "1"})


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("NormalScale", "abc", "a finite number"),
        ("NormalScale", "", "a finite number"),
        ("SearchScale", "nan", "a finite number"),
        ("SearchDepth", "inf", "a finite number"),
        ("SearchDepth", "1e999", "a finite number"),
        ("SearchScale", "1,5", "a finite number"),
        ("RegistrationError", "0x10", "a finite number"),
        ("PM1Scale", "1 2", "a finite number"),
        ("NormalMode", "0.0", "an integer"),
        ("MinPoints4Stat", "5.5", "an integer"),
        ("MaxThreadCount", "all", "an integer"),
        ("M3C2VER", "1.0", "an integer"),
        ("ProjDestIndex", "\u0662", "an integer"),
        ("UseMedian", "yes", "true or false"),
        ("ExportStdDevInfo", "2", "true or false"),
        ("UsePrecisionMaps", "", "true or false"),
    ],
)
def test_malformed_value_names_key_and_value(tmp_path, key, value, expected):
    rejects(tmp_path, f"malformed value for {key}: {value!r} (expected {expected})", **{key: value})


@pytest.mark.parametrize("key", ["NormalScale", "SearchScale", "SearchDepth"])
@pytest.mark.parametrize("value", ["0", "-1.5"])
def test_non_positive_scale_or_depth_is_rejected(tmp_path, key, value):
    rejects(tmp_path, f"{key}={float(value)!r} must be > 0", **{key: value})


@pytest.mark.parametrize("key", ["NormalScale", "SearchScale", "SearchDepth"])
def test_required_key_missing(tmp_path, key):
    rejects(tmp_path, f"missing {key}", drop=[key])


def test_subsample_radius_rules(tmp_path):
    rejects(tmp_path, "missing SubsampleRadius", SubsampleEnabled="true")
    rejects(
        tmp_path, "SubsampleRadius=0.0 must be > 0", SubsampleEnabled="true", SubsampleRadius="0"
    )


def test_registration_error_rules(tmp_path):
    rejects(tmp_path, "missing RegistrationError", RegistrationErrorEnabled="true")
    rejects(tmp_path, "RegistrationError=-0.1 must be >= 0", RegistrationErrorEnabled="true",
            RegistrationError="-0.1")


def test_min_points_rules(tmp_path):
    rejects(tmp_path, "missing MinPoints4Stat", UseMinPoints4Stat="true")
    rejects(tmp_path, "MinPoints4Stat=0 must be >= 1", UseMinPoints4Stat="true", MinPoints4Stat="0")


def test_negative_thread_count_is_rejected(tmp_path):
    rejects(tmp_path, "MaxThreadCount=-2 must be >= 0", MaxThreadCount="-2")


@pytest.mark.parametrize("index", ["3", "-1"])
def test_invalid_proj_dest_index_is_rejected(tmp_path, index):
    rejects(
        tmp_path,
        f"ProjDestIndex={index} is not a CloudCompare output placement",
        ProjDestIndex=index,
    )


def test_missing_version_is_rejected(tmp_path):
    rejects(tmp_path, "missing M3C2VER", drop=["M3C2VER"])


def test_other_version_is_rejected(tmp_path):
    rejects(tmp_path, "M3C2VER=2 is not supported", M3C2VER="2")


def test_missing_general_section_is_rejected(tmp_path):
    rejects(tmp_path, "no [General] section", text="; nothing here\n")
    rejects(tmp_path, "no [General] section", text="")


def test_keys_before_any_section_are_rejected(tmp_path):
    rejects(tmp_path, "line 1: 'M3C2VER=1' comes before the [General] section",
            text="M3C2VER=1\n[General]\nNormalScale=1\n")


def test_other_section_is_rejected(tmp_path):
    text = AUTZEN_BMX + "[Extra]\nNormalScale=3\n"
    rejects(tmp_path, "unexpected section [Extra]", text=text)


def test_general_section_with_wrong_case_is_rejected(tmp_path):
    rejects(tmp_path, "section [general] must be spelled [General]",
            text=AUTZEN_BMX.replace("[General]", "[general]"))


def test_duplicate_key_is_rejected(tmp_path):
    rejects(tmp_path, "line 29: duplicate key 'NormalScale'", text=AUTZEN_BMX + "NormalScale=3\n")


def test_duplicate_section_is_rejected(tmp_path):
    rejects(tmp_path, "duplicate section [General]", text=AUTZEN_BMX + "[General]\n")


def test_line_without_equals_is_rejected(tmp_path):
    rejects(tmp_path, "line 3: cannot parse 'NormalScale 2' (expected Key=value)",
            text="[General]\nM3C2VER=1\nNormalScale 2\n")


def test_missing_file_is_rejected(tmp_path):
    path = tmp_path / "absent.txt"
    expected = f"{path}: no such file"
    with pytest.raises(UsageError, match=re.escape(expected)):
        read_cloudcompare_params(path)


def test_directory_is_rejected(tmp_path):
    with pytest.raises(UsageError, match=re.escape(f"{tmp_path}: is a directory")):
        read_cloudcompare_params(tmp_path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_fifo_is_rejected_without_blocking(tmp_path):
    path = tmp_path / "params.fifo"
    os.mkfifo(path)
    with pytest.raises(UsageError, match="not a regular file"):
        read_cloudcompare_params(path)


def test_binary_file_is_rejected(tmp_path):
    path = tmp_path / "cloud.las"
    path.write_bytes(b"LASF\0\0\x01\x02" * 8)
    with pytest.raises(UsageError, match=re.escape(f"{path}: not a CloudCompare parameter file")):
        read_cloudcompare_params(path)


def test_oversized_file_is_rejected(tmp_path):
    path = write(tmp_path, AUTZEN_BMX + ";" + "x" * (1 << 20) + "\n")
    with pytest.raises(UsageError, match="too large"):
        read_cloudcompare_params(path)


# --- what QSettings writes or tolerates ---------------------------------------------------------


def test_crlf_comments_blank_lines_and_quotes(tmp_path):
    text = (
        "; written by hand\n"
        "# another comment\n"
        "\n"
        "[General]\n"
        "\n"
        "SearchDepth = \"5.5\"\n"
        "; keys in any order\n"
        "  NormalScale=2.780864 ; inline comment\n"
        "M3C2VER=1\n"
        "\n"
        "NormalPreferedOri=\"4\"\n"
        "SearchScale='5.780864'\n"
        "UseSinglePass4Depth=\"true\"   ; quoted boolean\n"
        "ProjDestIndex=2\n"
        "ExportStdDevInfo=true\n"
        "ExportDensityAtProjScale=true\n"
        "MaxThreadCount=8\n"
    )
    path = write(tmp_path, text, newline="\r\n")
    assert b"\r\n" in path.read_bytes()
    assert read_cloudcompare_params(path) == AUTZEN_BMX_OPTIONS


def test_crlf_autzen_bmx_file_with_bom(tmp_path):
    path = tmp_path / "params.txt"
    path.write_bytes(b"\xef\xbb\xbf" + AUTZEN_BMX.replace("\n", "\r\n").encode())
    assert read_cloudcompare_params(path) == AUTZEN_BMX_OPTIONS


def test_unterminated_quote_is_malformed(tmp_path):
    rejects(tmp_path, "malformed value for SearchDepth: '\"5.5'", SearchDepth='"5.5')


def test_keys_in_reverse_order(tmp_path):
    lines = AUTZEN_BMX.splitlines()
    text = "\n".join([lines[0]] + lines[:0:-1]) + "\n"
    assert read_cloudcompare_params(write(tmp_path, text)) == AUTZEN_BMX_OPTIONS
