"""`m3c2 classify train` and `m3c2 classify apply` (docs/classify.md). Registered by
m3c2kit.cli.main.make_parser through `classify_parsers`."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from .command_index import summary
from ..analysis.common import figure_format
from .integers import COUNT_MAX, integer
from .options import add, add_table_option
from ..base.errors import UsageError
from ..io import read_cloud, write_cloud_table
from ..io.atomic import staged_outputs
from ..io.collisions import check_outputs
from ..io.files import add_drop_nonfinite_option
from ..settings.parsers import normal_scales
# The classifier's modules are imported by the commands that use them (issue 45: building the
# parser of every m3c2 run imported them).

DEFAULT_SCALE_FACTORS = (4, 6, 8, 12, 16, 24, 32)  # times the point spacing sqrt(XY area / N)


def classify_parsers(sub) -> None:
    """Adds `classify` with its `train` and `apply` subcommands."""
    p = sub.add_parser("classify", help=summary("classify"),
                       description="Vegetation removal before comparing (the paper's section 4.3): train a "
                                   "classifier on labelled samples, apply it to a cloud (docs/classify.md).")
    csub = p.add_subparsers(dest="classify_command", required=True, parser_class=type(p))

    t = csub.add_parser("train", help="train a classifier from labelled samples",
                        description="A SAMPLE is FILE=LABEL (every point of FILE has that label) or a FILE "
                                    "whose --label-field (or --polygons) gives per-point labels. --seed draws "
                                    "the training points; --plot draws the samples in the classifier's plane.")
    t.add_argument("samples", nargs="+", metavar="SAMPLE",
                   help="labelled samples: FILE=LABEL (every point of FILE has that label), or a FILE with "
                        "--label-field or --polygons")
    t.add_argument("-o", "--output", type=Path, required=True, metavar="CLASSIFIER",
                   help="classifier file: JSON (any extension) or CloudCompare .prm (integer labels)")
    t.add_argument("--scales", help="sphere DIAMETERS: a list 'a,b,c' or MIN:MAX:STEP (default: 4 to 32 times "
                                    "the point spacing sqrt(XY area / N) of the first sample, 7 scales)")
    t.add_argument("--label-field", help="per-point labels of a FILE sample, e.g. classification")
    t.add_argument("--label-values", help="with --label-field: VALUE=LABEL,... the values used and their labels "
                                          "(e.g. 2=ground,1=other,6=other); others are not used (default: every "
                                          "value is its own label)")
    t.add_argument("--polygons", type=Path, help="GeoJSON polygons (XY) labelling the points of FILE samples")
    t.add_argument("--polygon-property", default="label", help="the polygons' label property (default label)")
    t.add_argument("--min-points", type=integer(1, COUNT_MAX), default=3, help="fewest neighbours of a scale (default 3)")
    t.add_argument("--max-per-class", type=integer(0, COUNT_MAX), default=50_000,
                   help="training points drawn per class and sample, seeded (default 50000; 0: all)")
    add(t, "sample_seed", default=0)
    add(t, "plot")  # the samples in the classifier's plane
    add_table_option(t, "threads", filled=True)
    add(t, "quiet")
    add_drop_nonfinite_option(t)
    t.set_defaults(run=run_train)

    a = csub.add_parser("apply", help="classify every point of a cloud",
                        description="Writes the cloud with the predicted class in the classification field "
                                    "(or --label-field) and a 'confidence' field (0 to 1).")
    a.add_argument("cloud", type=Path, help="the point cloud to classify")
    a.add_argument("--classifier", type=Path, required=True, metavar="CLASSIFIER",
                   help="a classifier written by m3c2 classify train")
    a.add_argument("-o", "--output", type=Path, required=True,
                   help="the cloud with its class codes: .csv .txt .ply .las .laz")
    a.add_argument("--label-field", default="classification", help="field receiving the class code "
                                                                     "(default classification)")
    a.add_argument("--class-map", help="LABEL=CODE,... codes written for the classifier's labels (default: "
                                       "integer labels are their own codes)")
    a.add_argument("--unclassified", type=integer(CODE_MIN, CODE_MAX), default=0,
                   help="code of points without features (too few neighbours at the largest scale; default 0)")
    add_table_option(a, "threads", filled=True)
    add(a, "quiet")
    add_drop_nonfinite_option(a)
    a.set_defaults(run=run_apply)


def _say(args, text: str) -> None:
    if not args.quiet:
        print(text, file=sys.stderr)


def default_scales(xyz: np.ndarray) -> list[float]:
    span = np.ptp(xyz[:, :2], axis=0)
    area = float(span[0] * span[1]) if span.min() > 0 else float(span.max() ** 2)
    spacing = math.sqrt(area / len(xyz)) if area > 0 else 0.0
    if not spacing > 0:
        raise UsageError("cannot derive default scales from a sample without XY extent: give --scales")
    return [float(f"{f * spacing:.3g}") for f in DEFAULT_SCALE_FACTORS]


def _samples(args):
    from ..classify.labels import labels_from_field, labels_from_polygons, parse_mapping, parse_sample, read_polygons
    value_names = parse_mapping(args.label_values, "--label-values")
    polygons = read_polygons(args.polygons, args.polygon_property) if args.polygons else None
    if value_names and not args.label_field:
        raise UsageError("--label-values needs --label-field")
    out = []
    for text in args.samples:
        path, label = parse_sample(text)
        cloud = read_cloud(path, drop_nonfinite=args.drop_nonfinite)
        if label is not None:
            out.append((path, cloud.xyz, label))
        elif polygons is not None:
            out.append((path, cloud.xyz, labels_from_polygons(cloud.xyz, polygons, path)))
        elif args.label_field:
            out.append((path, cloud.xyz, labels_from_field(cloud, args.label_field, path, value_names)))
        else:
            raise UsageError(f"sample {text!r} has no label: give FILE=LABEL, --label-field NAME or --polygons FILE")
    return out


def _check_outputs(args, inputs: dict) -> None:
    """No output (-o, --plot) may be an input (m3c2kit.io.collisions), checked before any work."""
    check_outputs({"-o": args.output, "--plot": getattr(args, "plot", None)}, inputs)
    if getattr(args, "plot", None) is not None:
        figure_format(args.plot, extra="classify")


def run_train(args) -> int:
    from ..classify.labels import parse_sample
    from ..classify.model import classifier_bytes
    from ..classify.plot import save_training_figure, training_figure
    from ..classify.train import train_with_samples
    samples = {f"sample {text}": parse_sample(text)[0] for text in args.samples}
    _check_outputs(args, dict(samples, **{"polygons file": args.polygons}))
    if args.min_points < 3:
        raise UsageError(f"--min-points must be >= 3, got {args.min_points}")
    if args.max_per_class < 0:
        raise UsageError(f"--max-per-class must be >= 0, got {args.max_per_class}")
    samples = _samples(args)
    scales = normal_scales(args.scales, "--scales") if args.scales is not None else default_scales(samples[0][1])
    clf, X, y = train_with_samples([(xyz, labels) for _, xyz, labels in samples], scales,
                                   min_points=args.min_points, threads=args.threads,
                                   max_per_class=args.max_per_class or None, seed=args.seed)
    clf.info["samples"] = [str(path) for path, _, _ in samples]
    # The classifier and its figure appear together or not at all: a failed --plot left the
    # classifier written (issue 42).
    fig = training_figure(clf, X, y, args.seed) if args.plot else None
    data = classifier_bytes(args.output, clf)
    with staged_outputs([p for p in (args.output, args.plot) if p]) as staged:
        staged[args.output].write_bytes(data)
        if fig is not None:
            save_training_figure(fig, staged[args.plot], args.plot)
    tr = clf.info["training"]
    lines = [f"scales (diameters): {', '.join(f'{s:g}' for s in clf.scales)}",
             "training points: " + ", ".join(f"{c} {n}" for c, n in tr["points"].items())
             + (f" ({tr['points_without_features']} without features, not used)" if tr["points_without_features"] else ""),
             f"training balanced accuracy: {100 * tr['balanced_accuracy']:.2f} % ("
             + ", ".join(f"{c} recall {100 * r:.2f} %" for c, r in tr["recall"].items()) + ")"]
    for b in clf.binaries:
        lines.append(f"{b.class1} / {b.class2}: boundary at {b.info['boundary_angle_deg']:+.0f} degrees from the "
                     f"discriminant axis; each scale alone (balanced accuracy):")
        for s in sorted(b.info["scale_power"], key=lambda s: -s["scale"]):
            lines.append(f"  {s['scale']:>10g}  {100 * s['balanced_accuracy']:6.2f} %")
    lines.append(f"classifier written to {args.output}" + (f", plot to {args.plot}" if args.plot else ""))
    _say(args, "\n".join(lines))
    return 0


#: The class codes apply writes (--class-map, --unclassified): 32-bit integers, far beyond any class
#: scheme (LAS: 0 to 255); a larger one overflowed numpy's int64 with a traceback.
CODE_MIN, CODE_MAX = -2**31, 2**31 - 1


def class_codes(clf, spec: str | None) -> dict[str, int]:
    from ..classify.labels import parse_mapping
    mapping = parse_mapping(spec, "--class-map")
    unknown = [k for k in mapping if k not in clf.labels]
    if unknown:
        raise UsageError(f"--class-map: {', '.join(unknown)} not a class of the classifier "
                         f"(its classes: {', '.join(clf.labels)})")
    codes = {}
    for label in clf.labels:
        text = mapping.get(label, label)
        try:
            codes[label] = int(text)
        except ValueError:
            raise UsageError(f"class {label!r} has no integer code: give --class-map {label}=CODE") from None
        if not CODE_MIN <= codes[label] <= CODE_MAX:
            raise UsageError(f"--class-map: the code {text} of class {label!r} is out of range: codes are integers from "
                             f"{CODE_MIN} to {CODE_MAX}")
    return codes


def run_apply(args) -> int:
    from ..classify.apply import classify
    from ..classify.model import read_classifier
    _check_outputs(args, {"input cloud": args.cloud, "classifier file": args.classifier})
    clf = read_classifier(args.classifier)
    codes = class_codes(clf, args.class_map)
    cloud = read_cloud(args.cloud, drop_nonfinite=args.drop_nonfinite)
    p = classify(clf, cloud.xyz, threads=args.threads)
    table = np.array([codes[c] for c in clf.labels] + [args.unclassified], dtype=np.int64)
    code = table[p.index]
    field = args.label_field
    fields = dict(cloud.fields)
    old = fields.get(field)
    dtype = np.asarray(old).dtype if old is not None else (np.uint8 if 0 <= code.min() and code.max() <= 255
                                                           else np.float64)
    if np.dtype(dtype).kind in "ui":
        info = np.iinfo(dtype)
        if code.min() < info.min or code.max() > info.max:
            raise UsageError(f"class codes {sorted(set(table.tolist()))} do not fit the {field!r} field ({dtype})")
    fields[field] = code.astype(dtype)
    fields["confidence"] = p.confidence
    write_cloud_table(args.output, cloud.xyz, fields, like=cloud)
    counts = ", ".join(f"{c} -> {codes[c]}: {int(np.count_nonzero(p.index == k))}" for k, c in enumerate(clf.labels))
    missing = int(np.count_nonzero(p.index < 0))
    _say(args, f"{len(code)} points classified ({counts}" + (f"; {missing} without features -> {args.unclassified}"
                                                            if missing else "") + f"); written to {args.output}")
    return 0
