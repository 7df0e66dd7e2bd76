"""The provider inside QGIS (QgsApplication headless, Debian's python3): the result layer's
renderer and fields, the rasters' style, progress, Cancel (nothing left), layers as inputs.
Run by scripts/check-qgis.sh."""
import json
import os
import signal
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import COMPARED, PLUGINS, REFERENCE, Folder, environment, m3c2, run_tests  # noqa: E402

os.environ.update(environment())
sys.path.insert(0, PLUGINS)
sys.path.append("/usr/share/qgis/python/plugins")  # QGIS's Processing plugin

from qgis.core import (QgsApplication, QgsProcessingContext, QgsProcessingException, QgsProcessingFeedback,  # noqa: E402
                       QgsProject, QgsRasterLayer, QgsVectorLayer)

APP = QgsApplication([], False)
APP.initQgis()
from processing.core.Processing import Processing  # noqa: E402

Processing.initialize()
from m3c2kit_processing import runner, style  # noqa: E402
from m3c2kit_processing.provider import M3C2kitProvider  # noqa: E402

PROVIDER = M3C2kitProvider()
QgsApplication.processingRegistry().addProvider(PROVIDER)
SMALL = {"CORE_SPACING": 20, "NORMAL_SCALE": "16", "PROJECTION_SCALE": 10, "MAX_DEPTH": 30}


class Recorder(QgsProcessingFeedback):
    def __init__(self):
        super().__init__()
        self.percents, self.errors, self.commands, self.infos, self.warnings = [], [], [], [], []

    def setProgress(self, value):  # noqa: N802 - QGIS's name
        self.percents.append(value)
        super().setProgress(value)

    def reportError(self, error, fatalError=False):  # noqa: N802,N803 - QGIS's names
        self.errors.append(error)

    def pushWarning(self, warning):  # noqa: N802 - QGIS's name
        self.warnings.append(warning)
        super().pushWarning(warning)

    def pushCommandInfo(self, info):  # noqa: N802 - QGIS's name
        self.commands.append(info)

    def pushInfo(self, info):  # noqa: N802 - QGIS's name
        self.infos.append(info)
        super().pushInfo(info)

    def pushConsoleInfo(self, info):  # noqa: N802 - QGIS's name
        self.infos.append(info)
        super().pushConsoleInfo(info)


def run(algorithm, parameters, feedback=None):
    alg = QgsApplication.processingRegistry().createAlgorithmById(f"m3c2kit:{algorithm}")
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    feedback = feedback or Recorder()
    results, ok = alg.run(parameters, context, feedback)
    return results, ok, context, feedback


def summary_range(stdout_lines):
    """min and max of the distance from m3c2's own summary line ('distance: median ..., min A, max B')."""
    line = next(line for line in stdout_lines if line.startswith("distance: "))
    words = line.replace(",", "").split()
    return float(words[words.index("min") + 1]), float(words[words.index("max") + 1])


def test_result_layer_has_every_column_and_the_distance_style():
    with Folder() as d:
        out = os.path.join(d, "change.laz")
        results, ok, context, feedback = run("compare", dict(SMALL, REFERENCE=REFERENCE, COMPARED=COMPARED, OUTPUT=out))
        assert ok, feedback.errors
        assert results["OUTPUT_LAYER"] == out + ".gpkg"
        info = json.loads(m3c2("info", out, "--json").stdout)
        # loaded as QGIS loads it: the style saved in the GeoPackage is the layer's default
        layer = QgsVectorLayer(results["OUTPUT_LAYER"], "change", "ogr")
        assert layer.isValid() and layer.featureCount() == info["point_count"] == 499
        names = [f.name() for f in layer.fields() if f.name() != "fid"]
        assert names == ["x", "y", "z"] + info["fields"], names
        kinds = {f.name(): f.typeName().lower() for f in layer.fields()}
        # counts, flags and codes stay integers (issue 44: every column was Real); measures stay Real
        assert all(kinds[n].startswith(("int", "mediumint")) for n in ("n1", "n2", "significant", "status")), kinds
        assert all(kinds[n] in ("real", "double") for n in ("distance", "lod")), kinds
        logged = "\n".join(feedback.infos)
        assert '"point_count"' not in logged and '"fields"' not in logged  # the internal m3c2 info --json
        check_distance_renderer(layer)
        # the post-processor Processing runs on the loaded layer styles one without a saved style too
        details = context.layersToLoadOnCompletion()[results["OUTPUT_LAYER"]]
        plain = QgsVectorLayer(results["OUTPUT_LAYER"], "plain", "ogr", QgsVectorLayer.LayerOptions(True, False))
        details.postProcessor().postProcessLayer(plain, context, feedback)
        check_distance_renderer(plain)
        # the values: m3c2's own summary of the run (printed before writing), to the LAZ's 0.1 mm
        direct = m3c2("compare", REFERENCE, COMPARED, "-o", os.path.join(d, "again.laz"), "--core-spacing", "20",
                      "--normal-scale", "16", "--projection-scale", "10", "--max-depth", "30")
        lo, hi = summary_range(direct.stdout.splitlines())
        values = [number(f["distance"]) for f in layer.getFeatures() if number(f["distance"]) is not None]
        assert abs(min(values) - lo) <= 1.5e-4 and abs(max(values) - hi) <= 1.5e-4, (min(values), max(values), lo, hi)
        significant = [number(f["significant"]) for f in layer.getFeatures()]
        flagged = int(next(w for w in direct.stdout.splitlines()[0].split(",") if w.strip().endswith("significant changes")).split()[0])
        assert set(significant) <= {0.0, 1.0, None} and significant.count(1.0) == flagged  # m3c2's summary


def number(value):
    """A feature's number as a float, None for NULL (a QVariant in QGIS 3)."""
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def check_distance_renderer(layer):
    renderer = layer.renderer()
    assert renderer.type() == "graduatedSymbol" and renderer.classAttribute() == "distance", renderer.type()
    ranges = renderer.ranges()
    assert len(ranges) == style.CLASSES
    for low, high in zip(ranges, reversed(ranges)):  # symmetric about 0
        assert abs(low.lowerValue() + high.upperValue()) < 1e-9 and abs(low.upperValue() + high.lowerValue()) < 1e-9
    middle = ranges[len(ranges) // 2]  # the neutral class: |d| <= the layer's median LOD (issue 44)
    lods = sorted(number(f["lod"]) for f in layer.getFeatures() if number(f["lod"]) is not None and number(f["lod"]) > 0)
    assert abs(middle.upperValue() - lods[len(lods) // 2]) < 1e-9 and abs(middle.lowerValue() + middle.upperValue()) < 1e-12
    unit = style.unit_of(layer)
    assert "no significant change" in middle.label() and f"{middle.upperValue():.3g}{' ' + unit if unit else ''} (" \
        in middle.label(), middle.label()  # in the projected CRS's unit; none for a layer without one (degrees)
    assert unit in ("", "m"), unit
    assert middle.symbol().color().name() == style.NEUTRAL_COLOUR
    assert not middle.symbol().dataDefinedProperties().property(style._opacity_property()).isActive()
    magnitudes = sorted(abs(number(f["distance"])) for f in layer.getFeatures() if number(f["distance"]) is not None)
    assert abs(ranges[-1].upperValue() - magnitudes[-1]) < 1e-9  # the outer classes reach every point
    inner = magnitudes[int(0.95 * len(magnitudes))]  # the inner classes span the 95th percentile of |distance|
    assert abs(ranges[-2].upperValue() - inner) < 1e-9 and inner < magnitudes[-1]
    first, last = ranges[0].symbol().color(), ranges[-1].symbol().color()
    assert first.blue() > first.red() and last.red() > last.blue()  # lowering blue, raising red
    for r in ranges[:len(ranges) // 2] + ranges[len(ranges) // 2 + 1:]:  # not-significant points faded
        prop = r.symbol().dataDefinedProperties().property(style._opacity_property())
        assert prop.isActive() and '"significant" = 1' in prop.expressionString(), prop.expressionString()
        assert f", {style.FADED_OPACITY})" in prop.expressionString()


def test_the_legend_unit_is_the_projected_crs_unit():
    from qgis.core import QgsVectorLayer
    assert style.unit_of(QgsVectorLayer("PointZ?crs=EPSG:32617", "utm", "memory")) == "m"
    assert style.unit_of(QgsVectorLayer("PointZ?crs=EPSG:4326", "lonlat", "memory")) == ""  # never degrees
    assert style.unit_of(QgsVectorLayer("PointZ", "none", "memory")) == ""
    edges = style.class_edges([-0.3, -0.1, 0.05, 0.2, 0.4] * 20, lod=0.02)
    assert len(edges) == style.CLASSES + 1 and edges[style.CLASSES // 2 + 1] == 0.02
    labels = style.class_labels(edges, "m", True)
    assert labels[style.CLASSES // 2] == "|d| <= 0.02 m (within the typical LOD: no significant change)"
    assert labels[-1].startswith("+") and labels[0].startswith("-") and labels[-1].endswith(" m")


def test_rasters_are_styled_symmetric_about_zero():
    with Folder() as d:
        out = os.path.join(d, "grid.csv")
        results, ok, context, feedback = run("compare", dict(REFERENCE=REFERENCE, COMPARED=COMPARED, GRID_CELL=25,
                                                             MAX_DEPTH=30, OUTPUT=out))
        assert ok, feedback.errors
        path = results["DISTANCE_RASTER"]
        layer = QgsRasterLayer(path, "distance")
        assert layer.isValid()
        context.layersToLoadOnCompletion()[path].postProcessor().postProcessLayer(layer, context, feedback)
        renderer = layer.renderer()
        assert renderer.type() == "singlebandpseudocolor"
        assert renderer.classificationMin() == -renderer.classificationMax() > -1e300
        items = renderer.shader().rasterShaderFunction().colorRampItemList()
        assert items[0].color.blue() > items[0].color.red() and items[-1].color.red() > items[-1].color.blue()


def test_progress_reaches_the_feedback():
    assert runner.progress_of('{"phase": "reading", "done": 1, "total": 2, "percent": 5.0}') == 5.0
    assert runner.progress_of('{"phase": "writing", "done": 1, "total": 1, "percent": 100.0}\r') == 100.0
    assert runner.progress_of("m3c2: warning: something") is None
    assert runner.progress_of('{"phase": "reading", "percent": "x"}') is None
    with Folder() as d:
        results, ok, context, feedback = run("compare", dict(SMALL, REFERENCE=REFERENCE, COMPARED=COMPARED,
                                                             OUTPUT=os.path.join(d, "p.csv")))
        assert ok and feedback.percents and feedback.percents[-1] == 100.0, feedback.percents
        assert feedback.percents == sorted(feedback.percents) and len(set(feedback.percents)) >= 4, feedback.percents
        assert not any('"phase"' in line for line in feedback.infos), feedback.infos  # no internal JSON in the log
        assert feedback.commands[0].split()[1:3] == ["compare", REFERENCE]


def test_a_compare_with_only_its_clouds_and_an_output():
    """Issue 44: the scales left empty are chosen from the data; the log says which and why."""
    with Folder() as d:
        results, ok, context, feedback = run("compare", {"REFERENCE": REFERENCE, "COMPARED": COMPARED,
                                                         "OUTPUT": os.path.join(d, "auto.csv")})
        assert ok, feedback.errors
        assert any("scales chosen from the data by m3c2 suggest's rules" in line for line in feedback.infos), \
            feedback.infos
        assert os.path.getsize(os.path.join(d, "auto.csv")) > 0


def _stopped_child(parent):
    """A child process of `parent` stopped by SIGSTOP, or None."""
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if fields[0] == "T" and int(fields[1]) == parent:
                return int(entry)
    return None


def test_cancel_leaves_nothing():
    """m3c2 stops itself once every temporary of its output is written, before any rename (the
    worst moment: M3C2_TEST_SIGNAL_AT, m3c2kit.base.fault_hook); Cancel then stops the run and
    nothing is left in the folder."""
    os.environ["M3C2_TEST_SIGNAL_AT"] = "writing:SIGSTOP"
    try:
        with Folder() as d:
            feedback = Recorder()
            seen, finished = {}, threading.Event()

            def cancel_when_stopped():
                deadline = time.monotonic() + 60
                while time.monotonic() < deadline and "pid" not in seen:
                    pid = _stopped_child(os.getpid())
                    if pid is not None:
                        seen["pid"], seen["listing"] = pid, sorted(os.listdir(d))
                        feedback.cancel()
                        if not finished.wait(30):  # Cancel did not end it: fail, not hang
                            seen["hung"] = True
                            os.kill(pid, signal.SIGKILL)
                    time.sleep(0.05)

            watcher = threading.Thread(target=cancel_when_stopped)
            watcher.start()
            results, ok, context, _ = run("compare", dict(SMALL, REFERENCE=REFERENCE, COMPARED=COMPARED,
                                                          OUTPUT=os.path.join(d, "c.laz")), feedback)
            finished.set()
            watcher.join()
            assert "hung" not in seen, "Cancel did not stop m3c2"
            assert "pid" in seen, "m3c2 never stopped at 'writing'"
            assert seen["listing"], "the run was stopped before it staged anything: the test proves nothing"
            assert not ok
            assert os.listdir(d) == [], os.listdir(d)
            assert not os.path.exists(f"/proc/{seen['pid']}") or open(f"/proc/{seen['pid']}/stat").read().split()[2] == "Z"
    finally:
        del os.environ["M3C2_TEST_SIGNAL_AT"]


def test_progress_moves_through_the_compute_and_cancel_ends_the_run_within_a_second():
    """A run long enough to watch (Toronto at a 1 m core spacing, 29 normal scales: about 15 s):
    the dialog's percent takes at least 5 distinct values inside the compute phase (between
    reading's 10 and writing's 95), and Cancel there ends the algorithm within 1 s, nothing left."""
    with Folder() as d:
        feedback = Recorder()
        seen, done = {}, threading.Event()

        def cancel_mid_compute():
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and not done.is_set():
                inside = {p for p in feedback.percents if 10.0 < p < 95.0}
                if len(inside) >= 5:
                    seen["inside"] = sorted(inside)
                    seen["cancelled_at"] = time.monotonic()
                    feedback.cancel()
                    return
                time.sleep(0.02)

        watcher = threading.Thread(target=cancel_mid_compute)
        watcher.start()
        parameters = dict(REFERENCE=REFERENCE, COMPARED=COMPARED, CORE_SPACING=1, NORMAL_SCALE="4:60:2",
                          PROJECTION_SCALE=10, MAX_DEPTH=30, OUTPUT=os.path.join(d, "long.laz"))
        results, ok, context, _ = run("compare", parameters, feedback)
        ended = time.monotonic()
        done.set()
        watcher.join()
        assert "cancelled_at" in seen, f"fewer than 5 percents inside the compute: {feedback.percents}"
        assert not ok
        print(f"Cancel took {ended - seen['cancelled_at']:.2f} s", file=sys.stderr)
        assert ended - seen["cancelled_at"] < 1.0, f"Cancel took {ended - seen['cancelled_at']:.2f} s"
        assert os.listdir(d) == [], os.listdir(d)


def test_scales_absurd_for_the_data_are_warned_in_the_log():
    """D and d typed 100 times too large (beyond the clouds' 900 m extent): m3c2's warnings, one
    naming each option, reach the log once each, as warnings."""
    with Folder() as d:
        results, ok, context, feedback = run("compare", dict(SMALL, REFERENCE=REFERENCE, COMPARED=COMPARED,
                                                             NORMAL_SCALE="1600", PROJECTION_SCALE=1000,
                                                             OUTPUT=os.path.join(d, "absurd.csv")))
        assert ok, feedback.errors
        absurd = [w for w in feedback.warnings if "extent" in w]
        assert len(absurd) == 2, feedback.warnings
        assert absurd[0].startswith("--normal-scale 1600") and absurd[1].startswith("--projection-scale 1000"), absurd


def test_a_vector_layer_is_not_an_input():
    layer = QgsVectorLayer("Point", "points", "memory")
    QgsProject.instance().addMapLayer(layer)
    try:
        with Folder() as d:
            results, ok, context, feedback = run("compare", dict(SMALL, REFERENCE=layer.id(), COMPARED=COMPARED,
                                                                 OUTPUT=os.path.join(d, "v.laz")))
            assert not ok and os.listdir(d) == []
    finally:
        QgsProject.instance().removeMapLayer(layer.id())


def test_the_compare_dialog_shows_cloudcompares_groups_in_order():
    """Each table parameter's label starts with its group (parameters.json's, m3c2kit.settings.groups),
    the groups in the file's order, the table's order within a group; the main part holds the scales."""
    from m3c2kit_processing import table
    with open(table.PATH, encoding="utf-8") as f:
        data = json.load(f)
    alg = QgsApplication.processingRegistry().createAlgorithmById("m3c2kit:compare")
    rows = {table.qgis_name(row): row for row in table.rows("compare")}
    shown = [p for p in alg.parameterDefinitions() if p.name() in rows]
    assert len(shown) == len(rows)
    groups = [rows[p.name()]["group"] for p in shown]
    assert groups == sorted(groups, key=data["groups"].index) and set(groups) == set(data["groups"])
    for p in shown:
        assert p.description() == f"{rows[p.name()]['group']}: {rows[p.name()]['label']}", p.description()
    by_name = {p.name(): p for p in shown}
    assert by_name["NORMAL_SCALE"].description().startswith("Scales: ")
    assert not is_advanced(by_name["PROJECTION_SCALE"]) and is_advanced(by_name["FLOAT64"])


def is_advanced(param) -> bool:
    from m3c2kit_processing.compat import ADVANCED
    return bool(param.flags() & ADVANCED)


def test_the_point_cloud_path_is_taken_only_with_pdal():
    from qgis.core import QgsProviderRegistry
    from m3c2kit_processing import results
    assert results.reads_point_clouds() == ("pdal" in QgsProviderRegistry.instance().providerList())


if __name__ == "__main__":
    code = run_tests(globals())
    APP.exitQgis()
    sys.exit(code)
