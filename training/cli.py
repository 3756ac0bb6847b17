"""`imufmu`: the command-line interface. Each subcommand makes one library call.

Problems the user can fix (bad file, bad option, bad model) print one line `imufmu VERB: error:
...` and exit with status 1; usage errors exit with status 2 (argparse). Notes of the loader (gaps
in time, one line per recording) are printed as the recordings are read, by every verb.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from contract.errors import ImuFusionError, one_line
from fmu.prebuilt import PACKAGE_DIR
from training.models.methods import METHODS, parse_method

#: Where `imufmu prebuild` writes by default: the package's own prebuilt folder.
PREBUILT_OUT = str(PACKAGE_DIR)


def _existing_file(path: str, what: str) -> Path:
    """Path of an existing file, else ImuFusionError naming it."""
    p = Path(path)
    if not p.is_file():
        raise ImuFusionError(f"{what} '{path}' not found")
    return p


def _method(text: str) -> tuple[str, str]:
    """Parse NAME=FORM for train --method (training.models.methods)."""
    try:
        return parse_method(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _variant(text: str) -> tuple[str, Path]:
    """Parse LABEL=FILE.ssv for --variant: a label that can name a file, and an existing file."""
    from fmu.references import check_label
    label, sep, path = text.partition("=")
    if not sep or not path:
        raise argparse.ArgumentTypeError(f"'{text}': expected LABEL=UNIT.ssv")
    try:
        check_label(label)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    if not Path(path).is_file():
        raise argparse.ArgumentTypeError(f"calibration file '{path}' not found")
    return label, Path(path)


def _param(text: str) -> tuple[str, float]:
    """Parse NAME=VALUE for --param: a known setting with a value of its declared type and range
    (contract.schema); a value that looks like the wrong unit is taken, with a warning on stderr."""
    from contract.schema import check_setting, unit_warning
    name, sep, value = text.partition("=")
    try:
        if not sep:
            raise ValueError
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER, got '{text}'") from None
    try:
        number = check_setting(name.strip(), number)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"'{text}': {e}") from None
    warning = unit_warning(name.strip(), number)
    if warning:
        print(f"imufmu: warning: --param {warning}", file=sys.stderr)
    return name.strip(), number


def _mounting(text: str) -> tuple[int, int, int]:
    """--mounting X,Y,Z: the codes mount_x, mount_y, mount_z of a mounting (contract.mounting)."""
    from contract.mounting import mounting_problem
    try:
        codes = tuple(int(c) for c in text.split(","))
    except ValueError:
        codes = ()
    if len(codes) != 3:
        raise argparse.ArgumentTypeError(f"expected three signed sensor axes such as 1,-2,-3, got '{text}'")
    problem = mounting_problem(codes)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return codes


def _degree(text: str):
    """--degree: 'auto' or an integer 0..3 (training.models.degree.parse_degree)."""
    from training.models.degree import parse_degree
    try:
        return parse_degree(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def cmd_simulate(args) -> None:
    """imufmu simulate SCENARIO.toml --out DIR [--seed N]."""
    from training.data.outputs import INTO, staged_output
    from training.simulator import simulate_to_dir
    with staged_output("simulate", args.out, args.force, INTO, inputs=[args.scenario]) as out:
        path = out.final(simulate_to_dir(args.scenario, out.path, seed=args.seed))
    print(f"wrote {path}")


def cmd_simulate_fleet(args) -> None:
    """imufmu simulate-fleet FLEET.toml --devices N --out DIR [--seed S]."""
    from training.data.outputs import staged_output
    from training.fleet.simulate import simulate_fleet
    with staged_output("simulate-fleet", args.out, args.force, inputs=[args.fleet]) as out:
        summary = out.final(simulate_fleet(args.fleet, args.devices, out.path, seed=args.seed))
    print(f"wrote {args.devices} unit folder(s) and {summary}")


def cmd_fleet_train(args) -> int:
    """imufmu fleet train FLEET_DIR --out OUT [--workers K | --scheduler ADDRESS] [--seed N]: exit
    status 0 when every unit was trained, EXIT_PARTIAL when some were, 1 when none was."""
    from training.completeness import EXIT_PARTIAL
    from training.data.outputs import staged_output
    from training.fleet.report import fleet_elm_summary, write_fleet_report
    from training.fleet.train import train_fleet, variant_label, write_fleet_fmu
    with staged_output("fleet train", args.out, args.force, inputs=[args.fleet_dir]) as out:
        results = train_fleet(args.fleet_dir, out.path, seed=args.seed, workers=args.workers,
                              scheduler=args.scheduler)
        json_path, md_path, doc = write_fleet_report(results, out.path, seed=args.seed, progress=True)
        fmu_path = write_fleet_fmu(results, out.path, fmi_version=args.fmi) if doc["trained"] else None
    json_path, md_path = out.final(json_path), out.final(md_path)
    print(f"trained {doc['trained']} of {len(results)} units; {len(doc['failed'])} failed, "
          f"{len({o['unit'] for o in doc['outliers']})} outlier unit(s)")
    for failure in doc["failed"]:
        print(f"  failed: {failure['unit']}: {failure['reason']}")
    for o in doc["outliers"]:
        print(f"  outlier: {o['unit']}: {o['parameter']} = {o['value']:.4g} {o['unit_of_value']} "
              f"({o['distance']:.1f} robust σ from the median {o['median']:.4g})")
    print(f"  {fleet_elm_summary(doc['elm'])}")
    print(f"wrote {json_path} and {md_path}")
    if fmu_path is not None:
        example = next(r.unit for r in results if r.model)
        print(f"wrote {out.final(fmu_path)}: one FMU (FMI {args.fmi}) with every trained unit's calibration.ssv as a "
              f"parameter set (imufmu run {out.final(fmu_path)} DATA --variant {variant_label(example)})")
    if doc["failed"]:
        status = EXIT_PARTIAL if doc["trained"] else 1
        print(f"imufmu fleet train: {len(doc['failed'])} of {len(results)} units failed (listed above); "
              f"exit status {status}", file=sys.stderr)
        return status
    return 0


def cmd_campaign(args) -> int:
    """imufmu campaign FMU DATA --runs N --vary NAME=DIST ... --out DIR [--workers K | --scheduler ADDRESS]
    [--sensor ImuSensor.fmu]: exit status 0 when every run gave its errors, EXIT_PARTIAL when some failed, 1 when
    all did."""
    from training.completeness import EXIT_PARTIAL
    from training.fleet.campaign import campaign_runs, parse_variation
    from training.fleet.campaign_report import failed_runs, write_campaign_report
    from training.data.outputs import staged_output
    variations = tuple(parse_variation(v, sensor=args.sensor is not None) for v in args.vary or [])
    fmu = _existing_file(args.fmu, "FMU")
    data = _existing_file(args.data, "data file")
    sensor = _existing_file(args.sensor, "sensor FMU") if args.sensor is not None else None
    with staged_output("campaign", args.out, args.force, inputs=[fmu, data, *([sensor] if sensor else [])]) as out:
        runs = campaign_runs(fmu, data, args.runs, variations, seed=args.seed, workers=args.workers,
                             scheduler=args.scheduler, sensor_path=sensor)
        md = out.final(write_campaign_report(runs, variations, fmu, data, args.seed, out.path, sensor_path=sensor))
    loop = f" in a closed loop with the virtual sensor {sensor}" if sensor else ""
    print(f"ran {len(runs)} co-simulations of {fmu} on {data}{loop}; wrote {md}")
    failed = failed_runs(runs)
    if failed:
        status = 1 if len(failed) == len(runs) else EXIT_PARTIAL
        print(f"imufmu campaign: {len(failed)} of {len(runs)} runs failed (first: run {failed[0]['run']}: "
              f"{failed[0]['failed']}); exit status {status}", file=sys.stderr)
        return status
    return 0


def cmd_closed_loop(args) -> None:
    """imufmu closed-loop --sensor S.fmu --fusion F.fmu DATA --out DIR [--seed N] [--importer ecospy|fmpy]."""
    from training.data.outputs import staged_output
    from training.sensor.closed_loop import closed_loop_to_folder
    sensor = _existing_file(args.sensor, "sensor FMU")
    fusion = _existing_file(args.fusion, "ImuFusion FMU")
    data = _existing_file(args.data, "data file")
    with staged_output("closed-loop", args.out, args.force, inputs=[sensor, fusion, data]) as out:
        _, paths, lines = closed_loop_to_folder(sensor, fusion, data, out.path, seed=args.seed, importer=args.importer)
        written = [out.final(p) for p in paths]
    print("\n".join(lines))
    print("wrote " + ", ".join(str(p) for p in written))


def cmd_train(args) -> int:
    """imufmu train DATA... --out DIR [--seed N] [--degree auto|P] [--allow-partial] [--allow-identity]:
    exit status EXIT_INCOMPLETE (model written) when a recorded triad is not fully calibrated and neither
    --allow-partial nor --allow-identity was given."""
    from training.completeness import EXIT_INCOMPLETE
    from training.data.outputs import staged_output
    from training.train import train_to_folder
    with staged_output("train", args.out, args.force, inputs=[*args.data, *([args.prior] if args.prior else [])]) as out:
        done = train_to_folder([_existing_file(p, "data file") for p in args.data], out.path, seed=args.seed,
                               degree=args.degree, allow_identity=args.allow_identity, prior_path=args.prior,
                               name=Path(args.out).resolve().name, methods=dict(args.method or []),
                               mounting=args.mounting)
    for note in done.notes:
        print(f"note: {note}")
    print()
    print(done.summary)
    print(f"wrote {out.final(done.model)}, {out.final(done.calibration)} (the FMU parameter values: "
          f"imufmu run FMU DATA --calibration) and {out.final(done.report)}")
    if done.gaps and not (args.allow_partial or args.allow_identity):
        print(f"imufmu train: {len(done.gaps)} recorded triad(s) not fully calibrated (INCOMPLETE CALIBRATION above); "
              f"the model was written; exit status {EXIT_INCOMPLETE} — pass --allow-partial to accept it", file=sys.stderr)
        return EXIT_INCOMPLETE
    return 0


def cmd_import(args) -> None:
    """imufmu import FILE --out NAME.csv.gz [--columns MAP] [--units MAP] [--rate HZ] [sidecar options]."""
    from training.data.importer import ImportOptions, import_recording
    from training.data.io import sidecar_path
    from training.data.outputs import FILE, staged_output
    options = ImportOptions(columns=tuple(args.columns or ()), units=tuple(args.units or ()), rate_hz=args.rate,
                            sensor=args.sensor, reference=args.reference, earth_field=args.earth_field,
                            site=args.site)
    sidecar = sidecar_path(args.out).name if args.out.endswith((".csv", ".csv.gz")) else None
    with staged_output("import", args.out, args.force, FILE, inputs=[args.file],
                       names=[sidecar] if sidecar else []) as out:
        print(import_recording(args.file, out.path, options, shown=args.out).summary)


def cmd_build_fmu(args) -> None:
    """imufmu build-fmu [--model DIR/model.json] --out FILE.fmu (without a model: the generic FMU)."""
    from training.fmu_build import build_fmu_from_model
    from training.data.outputs import FILE, staged_output
    model = _existing_file(args.model, "model artefact") if args.model else None
    variants = dict(args.variant or [])
    with staged_output("build-fmu", args.out, args.force, FILE,
                       inputs=([args.model] if args.model else []) + [str(p) for p in variants.values()]) as out:
        path = out.final(build_fmu_from_model(model, out.path, fmi_version=args.fmi, variants=variants))
    for label in variants:
        print(f"embedded parameter set '{label}' (imufmu run {path} DATA --variant {label})")
    print(f"wrote {path} (FMI {args.fmi}.0 co-simulation" + (")" if model else
          "; generic: no calibration compiled in, run it with --calibration UNIT.ssv)"))


def _sensor_parameter(text: str) -> tuple[str, float]:
    """Parse NAME=VALUE for build-sensor-fmu --set (a virtual-sensor parameter, contract/sensor_variables.py)."""
    from contract.sensor_variables import sensor_parameters
    name, sep, value = text.partition("=")
    known = [v.name for v in sensor_parameters()]
    if not sep or name not in known:
        raise argparse.ArgumentTypeError(f"'{text}' is not NAME=VALUE with NAME a virtual-sensor parameter "
                                         f"(e.g. {', '.join(known[6:9])}, ...; docs/virtual_sensor.md)")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}': {value!r} is not a number") from None


def cmd_build_sensor_fmu(args) -> None:
    """imufmu build-sensor-fmu --model model.json --out ImuSensor.fmu [--fmi 3] [--set NAME=VALUE ...]."""
    from training.data.outputs import FILE, staged_output
    from training.sensor.build import build_sensor_fmu, noise_summary_lines
    model = _existing_file(args.model, "model artefact")
    overrides = dict(args.set or [])
    with staged_output("build-sensor-fmu", args.out, args.force, FILE, inputs=[args.model]) as out:
        built, plan = build_sensor_fmu(model, out.path, fmi_version=args.fmi, overrides=overrides)
        path = out.final(built)
    print("\n".join(noise_summary_lines(plan, overrides)))
    print(f"wrote {path} (virtual sensor, FMI {args.fmi}.0 co-simulation; validate it with imufmu validate {path})")


def cmd_prebuild(args) -> None:
    """imufmu prebuild [--out DIR]: the runtime library and the generic FMUs, so that train and run need no compiler."""
    from training.data.outputs import staged_output
    from training.fmu_build import build_prebuilt
    with staged_output("prebuild", args.out, args.force) as out:
        paths = build_prebuilt(out.path)
    for kind, path in paths.items():
        print(f"{kind:8s} {out.final(path)}")
    print(f"prebuilt for this platform from these sources: where no C compiler is on PATH, train uses the runtime "
          f"library and build-fmu (without --model) the generic FMU{'' if args.out == PREBUILT_OUT else f' (set IMUFUSION_PREBUILT={args.out})'}")


def cmd_validate(args) -> None:
    """imufmu validate FILE.fmu (ImuFusion or virtual-sensor FMU): exit 1 when there is any problem."""
    from fmu.validator import validate_fmu, validation_checks
    checks: list[tuple[str, int]] = []
    path = _existing_file(args.fmu, "FMU")
    problems = validate_fmu(path, checks)
    results = dict(checks)
    for name in validation_checks(path):
        found = results.get(name)
        print(f"check {name}: " + ("not run (an earlier check failed)" if found is None
                                   else "ok" if found == 0 else f"FAILED ({found} problem(s))"))
    for p in problems:
        print(f"problem: {p}")
    if problems:
        first = problems[0].removeprefix(f"{args.fmu}: ")
        raise ImuFusionError(f"{args.fmu}: {len(problems)} problem(s); the first: {first}")
    print(f"{args.fmu}: 0 problems")


def cmd_run(args) -> None:
    """imufmu run FILE.fmu DATA --out OUT.csv [--param NAME=VALUE ...] [--calibration UNIT.ssv | --variant LABEL]."""
    from training.main_job import outputs_sidecar, run_recording
    from training.data.outputs import FILE, staged_output
    if args.calibration and args.variant:
        raise ImuFusionError("give --calibration or --variant, not both")
    calibration = _existing_file(args.calibration, "calibration file") if args.calibration else None
    with staged_output("run", args.out, args.force, FILE, names=[outputs_sidecar(args.out).name],
                       inputs=[args.fmu, args.data, *([args.calibration] if args.calibration else [])]) as out:
        done = run_recording(_existing_file(args.fmu, "FMU"), _existing_file(args.data, "data file"), out.path,
                             dict(args.param or []), calibration, args.variant)
    if calibration is not None or args.variant:
        print(f"calibration: {calibration or f'the FMU parameter set {args.variant!r}'} (coefficients, settings and "
              "auxiliary inputs in place of the FMU's own)")
    print("\n".join(done.frame))
    for message in done.log:
        print(f"FMU: {message}")
    for note in done.notes:
        print(f"note: {note}")
    print(f"wrote {out.final(done.path)} ({done.samples} samples) and {out.final(done.sidecar)} (the outputs' frame)")


def cmd_compare_thermal(args) -> None:
    """imufmu compare-thermal DATA... --out DIR [--runs N] [--seed N]."""
    from training.bench.compare_thermal import compare_thermal
    from training.data.outputs import staged_output
    paths = [_existing_file(p, "data file") for p in args.data]
    with staged_output("compare-thermal", args.out, args.force, inputs=paths) as out:
        compare_thermal(paths, out.path, runs=args.runs, seed=args.seed, train_fraction=args.train_fraction)
    print(f"wrote {Path(args.out) / 'compare_thermal.md'}")


def cmd_diagnose(args) -> None:
    """imufmu diagnose DATA... --model DIR/model.json --out REPORT_DIR."""
    from training.diagnosis.diagnose import diagnose
    from training.data.outputs import staged_output
    with staged_output("diagnose", args.out, args.force, inputs=[*args.data, args.model]) as out:
        paths = [_existing_file(p, "data file") for p in args.data]
        result = diagnose(paths, _existing_file(args.model, "model artefact"), out.path, seed=args.seed)
    selected = result.get("selected")
    what = "nothing significant left" if not selected else \
        f"selected {selected['name']} on {selected['target']}"
    print(f"{what}; {result['metric']}: {result['before']:.4g} -> {result['after']:.4g} "
          f"({result['improvement_pct']:.1f} %)")
    for it in result["iterations"]:
        s = it["selected"]
        print(f"  {s['name']} -> {s['target']}: {it['before']:.4g} -> {it['after']:.4g}"
              + "".join(f"; {x}" for x in s["readings"]))
    for note in result["notes"]:
        print(f"  note: {note}")
    print(f"wrote {Path(args.out) / 'diagnosis.json'}, report.md and model.json")


def cmd_noise(args) -> None:
    """imufmu noise DATA... --out DIR: noise.json, imu.yaml, allan_<triad>.png, noise.md."""
    from training.data.outputs import staged_output
    from training.noise.report import noise_to_folder, summary_lines
    paths = [_existing_file(p, "data file") for p in args.data]
    with staged_output("noise", args.out, args.force, inputs=paths) as out:
        done = noise_to_folder(paths, out.path, progress=True)
        written = [out.final(p) for p in (done.json, done.yaml, *done.plots, done.markdown)]
    print("\n".join(summary_lines(done.result.block)))
    for note in done.result.notes:
        print(f"note: {note}")
    print("wrote " + ", ".join(str(p) for p in written))


def cmd_bench(args) -> None:
    """imufmu bench broad|broad-trained [--trials ...] --out DIR | imufmu bench speed --out DIR |
    imufmu bench methods DATA... [--eval EVAL...] [--seed N] --out DIR."""
    from training.bench.bench import bench_broad, bench_speed
    from training.bench.bench_trained import bench_broad_trained
    from training.bench.methods_bench import bench_methods
    from training.data.outputs import staged_output
    if args.what == "methods" and not args.data:
        raise ImuFusionError("bench methods: give the calibration recordings (imufmu bench methods DATA... --out DIR)")
    if args.what != "methods" and (args.data or args.eval):
        raise ImuFusionError(f"bench {args.what} takes no recordings (DATA, --eval: bench methods only)")
    if args.what == "methods" and args.trials is not None:
        raise ImuFusionError("bench methods takes recordings, not --trials (imufmu bench methods DATA... --eval EVAL...)")
    paths = [_existing_file(p, "data file") for p in args.data]
    eval_paths = [_existing_file(p, "evaluation file") for p in args.eval or []]
    with staged_output("bench", args.out, args.force, inputs=[*paths, *eval_paths]) as out:
        if args.what == "methods":
            bench_methods(paths, out.path, eval_paths, seed=args.seed)
        elif args.what == "broad":
            bench_broad(args.trials, out.path)
        elif args.what == "broad-trained":
            bench_broad_trained(out.path, args.trials)
        else:
            bench_speed(out.path)
    print(f"wrote results to {args.out}")


def cmd_pipeline(args) -> None:
    """imufmu pipeline [--out DIR] [--seed N]: the main job on the bundled defaults."""
    from training.data.outputs import staged_output
    from training.main_job import check_summary, run_main_job
    from training.reports.report import summary_table
    with staged_output("pipeline", args.out, args.force) as out:
        summary = run_main_job(out.path, seed=args.seed)
    print()
    print(summary_table(summary))
    print(f"\nFMU: {out.final(summary.fmu_path)}  (validation problems: {len(summary.validation_problems)})")
    print(f"report: {Path(args.out) / 'report.md'}")
    check_summary(summary)


#: One example command per verb, shown at the end of its --help.
EXAMPLES = {
    "simulate": "imufmu simulate scenarios/calibration.toml --out data --seed 1",
    "simulate-fleet": "imufmu simulate-fleet scenarios/fleet/mems_grade.toml --devices 200 --out fleet --seed 0",
    "train": "imufmu train data/calibration.csv.gz --out model",
    "import": "imufmu import log.csv --out rec.csv.gz --units t=ms,gyr=deg/s,acc=g,mag=uT,temp=C",
    "fleet": "imufmu fleet train fleet --out fleet_models --workers 2",
    "campaign": "imufmu campaign ImuFusion.fmu data/eval_handheld.csv.gz --runs 1000 --vary noise_gyr=uniform(0,0.01) "
                "--vary declination=normal(0.05,0.01) --out campaign",
    "closed-loop": "imufmu closed-loop --sensor ImuSensor.fmu --fusion out/ImuFusion.fmu out/data/eval_handheld.csv.gz "
                   "--out loop --seed 1",
    "build-fmu": "imufmu build-fmu --model model/model.json --out ImuFusion.fmu --fmi 3",
    "build-sensor-fmu": "imufmu build-sensor-fmu --model model/model.json --out ImuSensor.fmu --set gyr_random_walk_x=3e-6",
    "prebuild": "imufmu prebuild --force",
    "validate": "imufmu validate ImuFusion.fmu",
    "run": "imufmu run ImuFusion.fmu data/eval_handheld.csv.gz --out outputs.csv --param declination=0.05",
    "compare-thermal": "imufmu compare-thermal data/thermal_plateaus.csv.gz --out thermal --runs 10",
    "diagnose": "imufmu diagnose data/calibration.csv.gz --model model/model.json --out diagnosis",
    "bench": "imufmu bench broad --trials 01 02 --out bench",
    "noise": "imufmu noise ../shared/data/pan_thermal/pan_etu_cold_chamber.csv.gz --out noise",
    "pipeline": "imufmu pipeline --out out --seed 0",
}


def _add_verb(sub, verb: str, help_text: str) -> argparse.ArgumentParser:
    """The subparser of `verb`, its --help ending with the verb's example command (EXAMPLES)."""
    return sub.add_parser(verb, help=help_text, epilog=f"example:\n  {EXAMPLES[verb]}",
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def _add_out(s: argparse.ArgumentParser, help_text: str, default: str | None = None) -> None:
    """--out (required unless it has a default) and --force: the rule of every verb's output
    (training.data.outputs.staged_output)."""
    s.add_argument("--out", required=default is None, default=default,
                   help=help_text + ("" if default is None else f" (default: {default})"))
    s.add_argument("--force", action="store_true",
                   help="replace an existing output (a folder only when it is an earlier imufmu output); the new "
                        "one is written beside it and moved into place only when complete. Without it an existing "
                        "output is kept and the verb stops")


def _add_fmu_out(s: argparse.ArgumentParser) -> None:
    """--out FILE.fmu (and --force) and --fmi 2|3 of the verbs that build an FMU."""
    _add_out(s, "FMU file to write")
    s.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (default 2)")


def _add_dask_options(s: argparse.ArgumentParser) -> None:
    """--workers K | --scheduler ADDRESS: where a distributed verb runs (training.fleet.engine)."""
    from training.fleet.engine import ADDRESS_FORM, CONNECT_TIMEOUT_S
    where = s.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="worker processes of the local Dask cluster (default: the cores available)")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help=f"address of a running Dask scheduler ({ADDRESS_FORM}) instead of a local cluster; "
                            f"it must answer, and have a worker, within {CONNECT_TIMEOUT_S} s each")


def _add_import_verb(sub) -> None:
    """The parser of `imufmu import` (README.md, 'Bringing your own file')."""
    s = _add_verb(sub, "import", "turn a CSV or MATLAB .mat file into imu-csv/1 (CSV + sidecar), with train's unit checks")
    s.add_argument("file", help="delimited text with a header row (',', ';', tab or whitespace; .gz allowed) or a "
                   "MATLAB .mat file (v4-v7; a v7.3 file is refused)")
    _add_out(s, "the recording to write, NAME.csv.gz or NAME.csv (+ NAME.json)")
    s.add_argument("--columns", action="append", metavar="MAP",
                   help="TARGET=COLUMN entries, e.g. t=Time,gyr_x=GyroX,... or per triad gyr=GX,GY,GZ (a .mat file: "
                        "variable or struct field names; gyr=gyro for an N×3 matrix); targets t, gyr, acc, mag, "
                        "gyr_x..mag_z, temp, aux_NAME. Unnamed targets are recognised by common column names. Repeatable")
    s.add_argument("--units", action="append", metavar="MAP",
                   help="QUANTITY=UNIT entries: gyr=rad/s|deg/s|mdps|rpm, acc=m/s2|g|mg, mag=uT|nT|mT|mG|G, "
                        "t=s|ms|us|ns|samples, temp=C|K|F; raw ADC counts with the value of one LSB: "
                        "gyr=counts:0.0152587890625deg/s (or counts:1/65.5deg/s), temp=counts:0.00294118C+36.53. "
                        "Wins over a unit in the header; a quantity with neither is refused. Repeatable")
    s.add_argument("--rate", type=float, default=None, metavar="HZ",
                   help="sample rate: t = n / HZ without a time column, t = (counter − first) / HZ for a sample "
                        "counter; with a time column it is the sidecar's rate_hz (checked against the median step)")
    s.add_argument("--sensor", default=None, metavar="TEXT", help="what the sensor is, for the sidecar")
    s.add_argument("--reference", default="none", metavar="KIND", help="the sidecar's reference kind (default none; "
                   "training/data/sidecar.py REFERENCES lists them)")
    field = s.add_mutually_exclusive_group()
    field.add_argument("--earth-field", default=None, metavar="NORM,DIP,DECL",
                       help="local field norm [µT], dip [°, down], declination [°, east]; an empty entry is unknown "
                            "(a leading minus needs '=': --earth-field=-48,-60,3)")
    field.add_argument("--site", default=None, metavar="LAT,LON,ALT_KM[,DATE]",
                       help="site (degrees, km, YYYY-MM-DD): train takes the IGRF field there "
                            "(a leading minus needs '=': --site=-33.9,18.4,0.1)")
    s.set_defaults(func=cmd_import)


def build_parser() -> argparse.ArgumentParser:
    """The one argparse parser with a subparser per verb; --version prints our distribution's
    name and version (contract.version)."""
    from contract.version import DISTRIBUTION, package_version
    p = argparse.ArgumentParser(prog="imufmu", description="ImuFusion: train, build, validate and "
                                "co-simulate the IMU calibration + attitude FMU.")
    p.add_argument("--version", action="version", version=f"imufmu ({DISTRIBUTION}) {package_version()}")
    sub = p.add_subparsers(dest="verb", required=True, metavar="VERB")
    s = _add_verb(sub, "simulate", "simulate a scenario into an imu-csv/1 file")
    s.add_argument("scenario")
    _add_out(s, "output folder: the recording is added to it (NAME.csv.gz + NAME.json)")
    s.add_argument("--seed", type=int, default=None, help="random seed (default: the scenario's)")
    s.set_defaults(func=cmd_simulate)
    s = _add_verb(sub, "simulate-fleet", "simulate N units of one sensor type, each with its own errors")
    s.add_argument("fleet", help="fleet file (TOML): the unit type and its calibration and test scenarios")
    s.add_argument("--devices", type=int, required=True, help="number of units")
    _add_out(s, "output folder: one folder per unit")
    s.add_argument("--seed", type=int, default=0, help="random seed of the fleet (default 0)")
    s.set_defaults(func=cmd_simulate_fleet)
    s = _add_verb(sub, "train", "train the models on calibration recordings")
    s.add_argument("data", nargs="+", help="imu-csv/1 files (.csv or .csv.gz); reference columns, an "
                   "attitude reference or a static sidecar are used when present, else self-calibration")
    _add_out(s, "output folder for model.json, calibration.ssv and calibration.md")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--degree", type=_degree, default="auto", metavar="{auto,0,1,2,3}",
                   help="temperature polynomial degree of G(T) and B(T). auto (default): chosen per triad from "
                        "the data — at most (distinct temperatures − 1), of 0..2 the one with the lowest error on the "
                        "held-out last quarter of every temperature band (ties: the lower); a number is a maximum (the data may force a "
                        "lower degree; the notes say so). The choice and its reason are in the summary, "
                        "calibration.md and the model's notes")
    s.add_argument("--allow-identity", action="store_true",
                   help="write the model anyway when nothing can be calibrated (identity) or a log without "
                        "reference shows no motion (gyro bias only), instead of failing")
    s.add_argument("--allow-partial", action="store_true",
                   help="exit 0 when a recorded triad is left wholly or partly uncalibrated (the summary opens with "
                        "it and the WARNINGS name it either way); without it, train writes the model and exits 3")
    s.add_argument("--prior", default=None, metavar="FLEET_JSON",
                   help="fleet.json from 'imufmu fleet train': fit each triad with a reference as the population's "
                        "most probable unit given this recording (a short recording then calibrates what it "
                        "does not observe from the population)")
    s.add_argument("--method", type=_method, action="append", metavar="NAME=FORM",
                   help="run a method in a chosen form, its stage switched on (repeatable): " + "; ".join(
                       f"{name}={'|'.join(forms)}" for name, forms in METHODS.items())
                   + " (the first form of each: as its source describes it; docs/methods.md)")
    s.add_argument("--mounting", type=_mounting, metavar="X,Y,Z",
                   help="declare the body axes: mount_x, mount_y, mount_z, the sensor axis each FRD body axis is "
                        "(1 = +x ... -3 = -z; a z-up board with x forward: 1,-2,-3); over any sidecar's \"mounting\". "
                        "Without it, the data decide by one rule with or without a reference (docs/fmu.md, Frames)")
    s.set_defaults(func=cmd_train)
    _add_import_verb(sub)
    s = _add_verb(sub, "fleet", "calibrate every unit of a fleet on Dask and describe the population")
    s.add_argument("action", choices=("train",))
    s.add_argument("fleet_dir", help="folder of unit folders (each with a calibration/ folder of recordings, "
                   "as simulate-fleet writes, or with its own recordings)")
    _add_out(s, "output folder: OUT/<unit>/model.json and calibration.ssv, fleet.json, fleet.md, ImuFusion.fmu (one FMU, "
                "every unit's set embedded)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the fleet's FMU (default 2)")
    _add_dask_options(s)
    s.set_defaults(func=cmd_fleet_train)
    s = _add_verb(sub, "campaign", "Monte-Carlo co-simulation of an FMU on Dask: parameter variations, noisy inputs")
    s.add_argument("fmu")
    s.add_argument("data", help="imu-csv/1 recording with truth (reference columns or ref_q)")
    s.add_argument("--runs", type=int, required=True)
    s.add_argument("--vary", action="append", metavar="NAME=DIST",
                   help="NAME=normal(MEAN,SIGMA) | uniform(LOW,HIGH) | choice(A,B,...); NAME an FMU parameter or "
                        "noise_gyr [rad/s], noise_acc [m/s²], noise_mag [µT] (σ of white noise added to that input); or "
                        "unit=FLEET_DIR: each run draws a unit of a fleet train folder and sets its calibration.ssv. "
                        "Repeatable")
    _add_out(s, "output folder: campaign.md, campaign.json, runs.csv, campaign.png")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--sensor", default=None, metavar="ImuSensor.fmu",
                   help="close the loop: each run drives this virtual-sensor FMU with the recording's truth and FMU "
                        "with its outputs; the sensor's noise seed is each run's own draw (column seed) unless --vary "
                        "seed=choice(...); its parameters (gyr_noise_density_x, ...) may be varied")
    _add_dask_options(s)
    s.set_defaults(func=cmd_campaign)
    s = _add_verb(sub, "closed-loop", "a recording's truth -> the virtual-sensor FMU -> the ImuFusion FMU in one "
                                      "co-simulation (docs/virtual_sensor.md): errors against truth")
    s.add_argument("data", help="imu-csv/1 recording with truth (ref_gyr, ref_acc, ref_q; ref_mag used when present)")
    s.add_argument("--sensor", required=True, metavar="ImuSensor.fmu", help="the virtual-sensor FMU")
    s.add_argument("--fusion", required=True, metavar="ImuFusion.fmu", help="the ImuFusion FMU")
    _add_out(s, "output folder: outputs.csv (aligned to the samples), closed_loop.png (attitude error), "
                "closed_loop.json")
    s.add_argument("--seed", type=int, default=0, help="the sensor's noise seed (default 0)")
    s.add_argument("--importer", choices=("ecospy", "fmpy"), default="ecospy",
                   help="the co-simulation master: ecospy (Ecos, fixed step; default) or fmpy (the recording's own "
                        "times, gaps allowed)")
    s.set_defaults(func=cmd_closed_loop)
    s = _add_verb(sub, "build-fmu", "write the trained model into the FMU sources and build it")
    s.add_argument("--model", help="model.json from 'imufmu train' (without it: the generic FMU, no calibration "
                                   "compiled in, for units' calibration.ssv files)")
    _add_fmu_out(s)
    s.add_argument("--variant", type=_variant, action="append", metavar="LABEL=UNIT.ssv",
                   help="embed a unit's calibration.ssv as parameter set LABEL (repeatable; FMI-LS-REF layout, "
                        "extra/org.fmi-standard.fmi-ls-ref/)")
    s.set_defaults(func=cmd_build_fmu)
    s = _add_verb(sub, "build-sensor-fmu", "the virtual-sensor FMU of a trained model: true motion in, what this "
                                           "unit outputs out (docs/virtual_sensor.md)")
    s.add_argument("--model", required=True, help="model.json from 'imufmu train'")
    _add_fmu_out(s)
    s.add_argument("--set", type=_sensor_parameter, action="append", metavar="NAME=VALUE",
                   help="a sensor parameter's start value, e.g. a data-sheet noise figure the data could not support "
                        "(repeatable; units: docs/virtual_sensor.md)")
    s.set_defaults(func=cmd_build_sensor_fmu)
    s = _add_verb(sub, "prebuild", "compile the runtime library and the generic FMUs once: train and run then need no "
                                   "C compiler (docs/fmu.md)")
    _add_out(s, "folder to write (the checkout's own, found without a setting; another one is used through env "
                "IMUFUSION_PREBUILT)", default=PREBUILT_OUT)
    s.set_defaults(func=cmd_prebuild)
    s = _add_verb(sub, "validate", "validate an FMU (model description, exports, smoke run)")
    s.add_argument("fmu")
    s.set_defaults(func=cmd_validate)
    s = _add_verb(sub, "run", "co-simulate a recording through the FMU with fmpy")
    s.add_argument("fmu")
    s.add_argument("data")
    _add_out(s, "CSV file for the FMU outputs")
    s.add_argument("--param", type=_param, action="append", metavar="NAME=VALUE",
                   help="FMU parameter (repeatable); declination and field_norm default to the sidecar")
    s.add_argument("--calibration", metavar="UNIT.ssv",
                   help="a unit's calibration.ssv (imufmu train writes it): its coefficients and settings are set "
                        "in the FMU before initialisation, so one FMU runs every unit")
    s.add_argument("--variant", metavar="LABEL", help="a parameter set embedded in the FMU (build-fmu --variant), "
                                                      "applied like --calibration")
    s.set_defaults(func=cmd_run)
    s = _add_verb(sub, "compare-thermal", "compare gyro temperature models on static recordings")
    s.add_argument("data", nargs="+", help="imu-csv/1 recordings of a static sensor")
    _add_out(s, "report folder")
    s.add_argument("--runs", type=int, default=50, help="Monte-Carlo repetitions (default 50)")
    s.add_argument("--train-fraction", type=float, default=0.6,
                   help="leading share of each recording (by time) used for training (default 0.6; "
                        "2/3 = the first four plateaus of scenarios/thermal_plateaus.toml)")
    s.add_argument("--seed", type=int, default=0)
    s.set_defaults(func=cmd_compare_thermal)
    s = _add_verb(sub, "diagnose", "find the effect the model lacks, add it, report before/after")
    s.add_argument("data", nargs="+", help="imu-csv/1 recordings with a reference")
    s.add_argument("--model", help="model.json from 'imufmu train' (without it: the generic FMU, no calibration "
                                   "compiled in, for units' calibration.ssv files)")
    _add_out(s, "report folder (diagnosis.json, report.md, model.json)")
    s.add_argument("--seed", type=int, default=0)
    s.set_defaults(func=cmd_diagnose)
    s = _add_verb(sub, "noise", "noise characterisation by Allan deviation: N, B, K per axis with CIs, imu.yaml "
                                "(docs/noise.md)")
    s.add_argument("data", nargs="+", help="imu-csv/1 recordings: a static log (sidecar reference 'static') is used "
                   "whole, any other recording by its rests")
    _add_out(s, "output folder (noise.json, imu.yaml, allan_<triad>.png, noise.md)")
    s.set_defaults(func=cmd_noise)
    s = _add_verb(sub, "bench", "benchmarks: BROAD attitude accuracy (filters, or trained FMU), runtime speed, or "
                                "each source method's forms beside the product's on your data")
    s.add_argument("what", choices=("broad", "broad-trained", "speed", "methods"))
    s.add_argument("data", nargs="*", help="methods: the calibration recordings (imu-csv/1) to train on")
    s.add_argument("--trials", nargs="*", default=None, help="BROAD trial prefixes (default: all)")
    s.add_argument("--eval", nargs="+", default=None, metavar="EVAL",
                   help="methods: recordings to evaluate on (default: the last quarter in time of each DATA "
                        "recording, the rest training; docs/methods.md)")
    s.add_argument("--seed", type=int, default=0, help="methods: the seed of every training (default 0)")
    _add_out(s, "output folder")
    s.set_defaults(func=cmd_bench)
    s = _add_verb(sub, "pipeline", "the main job on the bundled scenarios")
    _add_out(s, "output folder", default="out")
    s.add_argument("--seed", type=int, default=0)
    s.set_defaults(func=cmd_pipeline)
    return p


#: Exit status after Ctrl-C (SIGINT): 128 + 2, as a shell reports a command the signal ended.
EXIT_INTERRUPTED = 130


#: The stops received while the verb runs: a library whose C code calls back into Python may turn the
#: KeyboardInterrupt raised there into its own error (matplotlib's Agg renderer: "ValueError: Invalid bounding
#: box"); the verb still ends as interrupted.
_received: list[int] = []


def _stopped(signum, frame) -> None:
    """SIGINT (Ctrl-C) and SIGTERM (a job scheduler's stop, `kill`) end a verb alike: outputs cleaned up on the
    way, status 130."""
    _received.append(signum)
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `imufmu` console script; returns the exit status. SIGINT and SIGTERM are handled
    from the first line on: parsing imports much of the package (seconds), and a stop then is an
    interruption too."""
    words = sys.argv[1:] if argv is None else argv
    with _stops_interrupt(command_line=argv is None):
        try:
            return _run(argv)
        except Exception:  # an error while a stop was on its way is the stop, as a library reported it
            if not _received:
                raise
        except KeyboardInterrupt:  # Ctrl-C, SIGTERM: the context managers (Dask cluster, outputs) have closed
            pass
        print(f"imufmu {words[0] if words else ''}: interrupted".replace("  ", " "), file=sys.stderr)
    if argv is None:
        _exit_now(EXIT_INTERRUPTED)
    return EXIT_INTERRUPTED


def _exit_now(status: int) -> None:
    """End the process with `status` without the interpreter's teardown: after a stop the verb has
    cleaned up on its way out, and the teardown gets the status wrong. A native library stopped half-way
    through its initialisation can abort in it (once in 76 stopped `train` runs: "Fatal Python error:
    PyThreadState_Get ... finalizing", SIGABRT), and CPython 3.11 ends a `python -m` program by SIGINT at
    exit when a KeyboardInterrupt was ever raised inside an `exec` of a string (dataclasses, torch's
    imports), even one that `main` caught (CI of stop 41: train killed by SIGINT after "interrupted")."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


@contextmanager
def _stops_interrupt(command_line: bool) -> Iterator[None]:
    """SIGINT and SIGTERM raise KeyboardInterrupt inside the block. After it, on the command line, they take their
    default action (the verb is over: a stop while the interpreter exits ends it, with no traceback from an
    exit handler); called from Python, the caller's handlers are put back."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    stops = (signal.SIGINT, signal.SIGTERM)
    _received.clear()
    previous = {stop: signal.signal(stop, _stopped) for stop in stops}
    try:
        yield
    finally:
        for stop in stops:
            signal.signal(stop, signal.SIG_DFL if command_line else previous[stop])


def _run(argv: list[str] | None) -> int:
    """Parse argv and run the verb; its errors as one line and status 1."""
    from training.data.io import report_load_notes
    args = build_parser().parse_args(argv)
    try:
        with report_load_notes(lambda note: print(note, flush=True)):
            status = args.func(args)
    except ImuFusionError as e:  # messages embedding a tool's output may span lines: one line
        if _received:
            raise
        print(f"imufmu {args.verb}: error: {one_line(str(e))}", file=sys.stderr)
        return 1
    except OSError as e:  # unwritable output folder, disk full, ...
        if _received:
            raise
        print(f"imufmu {args.verb}: error: {e.filename or ''}: {one_line(e.strerror or str(e))}", file=sys.stderr)
        return 1
    return status or 0


if __name__ == "__main__":
    sys.exit(main())
