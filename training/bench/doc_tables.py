"""The one registry of the commands that write the tables of docs/*.md and README.md.

Every Markdown table in those files is one of:

- **measured**: a line `Command: `…`` in the paragraph just above or just below the table names
  the command that prints it; the command is a `TableGenerator.command` below and the table's
  header row is one of its `headers` (so running the command prints that table);
- **generated** by `python -m contract.generate` (inside a `generated:begin` region);
- **hand-written**: an HTML comment `<!-- hand-written: <why> -->` just above the table (reference
  lists and rules: settings, layouts, protocols, what a check covers).

tests/test_doc_tables.py holds the docs to this (`tables`, `coverage_problems`) and runs each
generator on its small input (`TableGenerator.small`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from training.bench.frame_agreement import TABLE_HEADER as FRAME_AGREEMENT_HEADER
from training.bench.methods_bench import TABLE_HEADER as METHODS_BENCH_HEADER
from training.models.methods import TABLE_HEADER as METHODS_HEADER

ROOT = Path(__file__).resolve().parents[2]
#: The shared measured data (read only); small forms that read it skip without it.
SHARED = ROOT.parent / "shared" / "data"
#: The files whose tables are covered.
DOC_FILES = ("README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md")))
#: Docs whose benchmark scripts other work owns: their tables are not checked yet (the lead
#: empties this list when those branches merge and their small forms are filled in below).
PENDING_DOCS = ()

COMMAND_TAG = re.compile(r"Command: `([^`]+)`")
HAND_WRITTEN_TAG = re.compile(r"<!-- hand-written: \S[^>]*-->")
GENERATED_TAG = "python -m contract.generate"


@dataclass(frozen=True)
class TableGenerator:
    """A command that prints tables of the docs.

    command: as the docs name it (`Command: `…``); headers: the header row of each table it
    prints, as printed; small: its small-input form, the arguments after the Python interpreter,
    run from the repository root ("{tmp}" is a scratch folder), None while it has none (see
    `why_not_small`); trains: the small form trains a model (each such run costs 10–30 s of CPU);
    needs: paths under SHARED the small form reads (it is skipped when one is missing)."""
    command: str
    headers: tuple[str, ...]
    small: tuple[str, ...] | None = None
    trains: bool = False
    needs: tuple[str, ...] = ()
    why_not_small: str = ""


def _call(statement: str) -> tuple[str, ...]:
    """Small form that runs one Python statement (a generator function with small arguments)."""
    return ("-c", statement)


_THERMAL_HEADER = ("| model | residual RMS [°/s] | RMS x / y / z [°/s] | 100 s variance [(°/s)²] | "
                   "bias stability [°/h] (vs uncomp.) | Allan min [°/h] (vs uncomp.) | "
                   "training CPU [s] (CV) | BP epochs (CV) |")
_BROAD_GROUPS = "| filter | undisturbed | disturbed | all |"
#: The tables of benchmarks/fleet_prior.py (one unit per row; the ratios against the bounds).
_FLEET_PRIOR_HEADERS = (
    "| unit | rate [°/s], full | rate [°/s], # s | rate [°/s], # s + prior | rate, slope-limited | field [µT], full "
    "| field [µT], # s | field [µT], # s + prior |",
    "| error | with prior ÷ full calibration (bound ≤ #) | with prior ÷ same # s alone (bound ≤ #) |")
#: The small form of benchmarks/fleet_prior.py: a 5-unit prior, one new unit, 30 s.
_FLEET_PRIOR_SMALL = ("benchmarks/fleet_prior.py", "--fleet-units", "5", "--units", "1", "--seconds", "30")
#: The table of benchmarks/fleet_prior.py --use-minutes (online bias learning on a unit's use recording).
_FLEET_USE_HEADER = ("| unit | use rate after 10 min [°/s], full | # s + prior | prior ÷ full (bound ≤ #) | full, no learning "
                     "| # s + prior, no learning | prior ÷ full, no learning |")

#: The table of benchmarks/noise_recovery.py (docs/noise.md).
_NOISE_RECOVERY_HEADER = ("| grade | triad | data | N error [%] min … max | B error [%] min … max "
                          "| K error [%] min … max | unsupported N / B / K | K truth inside its 68 % CI "
                          "| within bounds (N, K 10 %, B 25 %) |")
#: The table of benchmarks/noise_recovery.py --limit (docs/noise.md: the Cramér–Rao bound on K, the Whittle fit).
_NOISE_LIMIT_HEADER = ("| grade | triad | data | Cramér–Rao 1σ N / B / K [%] | K error [%] Allan fit: min … max (RMS) "
                       "| K error [%] Whittle fit: min … max (RMS) | K within 10 %: Allan / Whittle | Whittle N error [%] "
                       "| Whittle B error [%] | record for a 1σ of 10 % on K [h] |")

#: The table of benchmarks/unit_switch.py.
_UNIT_SWITCH = ("| FMI | units | switches | median per switch, ms | 95th percentile, ms | largest, ms | "
                "units bit-equal to their compiled FMU |")

#: The tables of training/sensor/closed_loop_bench.py (docs/virtual_sensor.md, "Closed loop").
_CLOSED_LOOP_HEADERS = (
    "| outputs shifted by [steps] | corrected rate error RMS [°/s], noise off |",
    "| recording | error | main job: the recording through ImuFusion | closed loop: its truth through ImuSensor and "
    "ImuFusion (ecospy, seed 0) | closed ÷ main |",
    "| recording | samples | ecospy [s] | fmpy [s] | ecospy = fmpy on Ecos's grid | largest metric difference, fmpy "
    "on the recording's times |")

#: The table of benchmarks/virtual_sensor.py (docs/virtual_sensor.md: the sensor's recording against the unit's).
_VIRTUAL_SENSOR = ("| axis | residual mean, unit (± 95 %) | residual mean, virtual (± 95 %) | both within their 95 % | "
                   "Allan τ: 95 % intervals overlap | virtual in unit's 95 % · unit in virtual's | σ_A(1 s) unit / "
                   "virtual | min σ_A unit / virtual |")

GENERATORS = (
    TableGenerator("python -m training.models.methods", (METHODS_HEADER,), small=("-m", "training.models.methods")),
    TableGenerator(
        "python benchmarks/virtual_sensor.py", (_VIRTUAL_SENSOR,),
        why_not_small="it needs the main job's trained model (`imufmu pipeline`, 26 s of training) and an hour of the "
                      "unit simulated at rest; tests/test_virtual_sensor.py pins its parts small (noise figures, the "
                      "flicker against the simulator's, the exact inverse)"),
    TableGenerator(
        "python -m training.sensor.closed_loop_bench out", _CLOSED_LOOP_HEADERS,
        why_not_small="it reads an `imufmu pipeline --out out` folder (26 s) and runs its three evaluation recordings "
                      "(13 300-29 680 samples) through two FMUs in both importers (~25 s); tests/test_closed_loop.py "
                      "runs the same functions on a small model and a 15 s recording"),
    TableGenerator(
        "python benchmarks/unit_switch.py --units 200 --compiled 3 --repeats 3", (_UNIT_SWITCH,),
        small=("benchmarks/unit_switch.py", "--units", "2", "--compiled", "0", "--repeats", "1"), trains=True),
    TableGenerator(
        "python benchmarks/unit_switch.py --fleet T --compiled 200 --repeats 3", (_UNIT_SWITCH,),
        why_not_small="T is a `fleet train` output of 200 units (11 min); the synthetic form above runs the same "
                      "cycle small"),
    TableGenerator(
        "imufmu bench broad-trained --out bench/broad-trained",
        (_BROAD_GROUPS,
         "| trial | VQF 9D (defaults) | ImuFusion FMU, no reference | ImuFusion FMU, no reference, enable_pf = 1 "
         "| ImuFusion FMU, attitude reference | ImuFusion FMU, attitude reference, enable_pf = 1 |",
         "| trial | training | spread raw | spread without filter | spread with filter | heading without | heading with |"),
        small=_call("from training.bench.bench_trained import bench_broad_trained; "
                    "bench_broad_trained('{tmp}', trials=['01'])"),
        trains=True, needs=("broad",)),
    TableGenerator(
        "imufmu bench broad --out bench/broad",
        (_BROAD_GROUPS, "| trial | ImuFusion | VQF 9D | x-io Fusion | Madgwick |",
         "| variant | undisturbed | disturbed | all |"),
        small=_call("from training.bench.bench import bench_broad; bench_broad(['01'], '{tmp}', samples=12000)"),
        needs=("broad",)),
    TableGenerator(
        "python benchmarks/euler_deviations.py",
        ("| recording | samples | heading, product's atan2(−m'_y, +m'_x) [°] | heading, source's atan2(−m'_y, −m'_x) "
         "[°] | source's form, P += σ²·dt: total / inclination / heading [°] | source's form, P through R: "
         "total / inclination / heading [°] | source's form, yaw de-tilted with the accelerometer's tilt: total / "
         "inclination / heading [°] | Python form vs C runtime, max [°] |",),
        small=("benchmarks/euler_deviations.py", "--trials", "01", "--samples", "12000"), needs=("broad",)),
    TableGenerator(
        "imufmu bench speed --out bench/speed",
        ("| stage | on [µs/sample] | off [µs/sample] | on − off [µs/sample] | on × VQF | off × VQF |",
         "| what | µs/sample | × VQF batch |"),
        small=_call("from training.bench.bench import bench_speed; bench_speed('{tmp}', samples=2000, fmu_samples=200)"),
        trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/two_soaks.py",
        ("| T [°C] | triad | raw | corrected | corrected / raw (largest) |",),
        small=("benchmarks/two_soaks.py",), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/calibrated_range.py",
        ("| T [°C] | triad | raw | extrapolated | clamped | continued (default) |",),
        small=("benchmarks/calibrated_range.py",), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bias_learning.py",
        ("| unit | bias learning | rate error after 10 min [°/s] | ÷ calibrated that day | 1 s means [°/s] "
         "| ÷ calibrated that day | learnt shift at the end [°/s] |",),
        small=("benchmarks/bias_learning.py", "--minutes", "11", "--hour", "2"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/thermal_continuation.py",
        ("| power-on | raw [°/s] | clamped [°/s] (reduction) | continued, default [°/s] (reduction) "
         "| extrapolated [°/s] (reduction) | continued − clamped [°/s] |",),
        why_not_small="simulates the 2.5 h plateau protocol and trains on its first 100 min (about 40 s); the "
                      "power-ons it measures are that protocol's last two plateaus"),
    TableGenerator(
        "python benchmarks/bench_protocol.py --seeds 0 --selfcal",
        ("| evaluation | trained on | settings | rate [°/s] | field [µT] | roll [°] | pitch [°] | yaw [°] "
         "| tilt [°] | heading [°] |",),
        why_not_small="trains three models on the full protocol and calibration sets (about 1 min); "
                      "no shorter input pins the sensor down"),
    TableGenerator(
        "python benchmarks/bench_xio_handheld.py --out bench/xio",
        ("| quantity | value |",),
        small=("benchmarks/bench_xio_handheld.py", "--out", "{tmp}"), trains=True,
        needs=("xio_handheld/xio_handheld.csv.gz",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_ferraris.py",
        ("| calibration | gravity-norm spread over the # rests [%] | gravity-norm spread over imucal's # face sections [%] "
         "| rest-to-rest gravity-direction error RMS [°] | rest pairs | ÷ imucal: rests / sections / direction (bound ≤ #) |",
         "| calibration | accelerometer scale factors x, y, z | gyro scale factors x, y, z |"),
        small=("benchmarks/bench_ferraris.py",), trains=True, needs=("imucal_ferraris/ferraris_session.csv.gz",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_twins.py",
        ("| twin | seed | protocol recognised | acc scale err max [%] | acc non-orth. err max [°] "
         "| gyr scale err max [%] | gyr non-orth. err max [°] | held at nominal |",),
        small=("benchmarks/bench_twins.py", "--seeds", "0", "--twins", "ferraris"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_time.py",
        ("| machine | wall [s], median of # | CPU [s], median of # | wall ≤ # s |",),
        small=("benchmarks/train_time.py", "--runs", "1"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_time.py --profile",
        ("| stage | time [s] | share |",),
        small=("benchmarks/train_time.py", "--profile"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --prior FLEET_OUT/fleet.json --units 20",
        _FLEET_PRIOR_HEADERS,
        small=(*_FLEET_PRIOR_SMALL, "--use-minutes", "11"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --fleet-units 12 --units 5 --use-minutes 20",
        (*_FLEET_PRIOR_HEADERS, _FLEET_USE_HEADER),
        why_not_small="the small form of the --prior FLEET_OUT/fleet.json --units 20 entry runs this code with "
                      "--use-minutes 11 (a second run would add its fleet training to the suite)"),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_prior.py --prior FLEET_OUT/fleet.json --units 20 "
        "--two-temperatures",
        _FLEET_PRIOR_HEADERS,
        small=(*_FLEET_PRIOR_SMALL, "--two-temperatures"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_speed.py --devices 200",
        ("| units | wall, 1 worker [s] | wall, 2 workers [s] | ratio (bound 0.6) | models equal |",),
        small=("benchmarks/fleet_speed.py", "--devices", "3"), trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/xio_mounting.py",
        ("| FMU run | mount_x, mount_y, mount_z | median roll [°] | tilt from level − x-io Fusion's, median / p90 [°] "
         "| inclination error against x-io Fusion, median / p90 [°] |",),
        small=("benchmarks/xio_mounting.py",), trains=True, needs=("xio_handheld/xio_handheld.csv.gz",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/frame_agreement.py", (FRAME_AGREEMENT_HEADER,),
        small=("benchmarks/frame_agreement.py", "--trials", "01", "--seconds", "60", "--train-seconds", "40"),
        trains=True, needs=("broad",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/state_cost.py",
        ("| FMU | state [KiB] | doStep [µs] | get + free [µs] | set [µs] | serialize [µs] | deserialize + free [µs] "
         "| set / doStep |",),
        small=("benchmarks/state_cost.py", "--calls", "20")),
    TableGenerator(
        "imufmu pipeline --out out",
        ("| scenario | metric | raw | ImuFusion FMU | bound | ok |",),
        why_not_small="the main job itself (simulate, train, build, validate, co-simulate; about 30 s); "
                      "tests/test_pipeline.py runs it and pins its numbers (the golden record)"),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py plateaus --out /tmp/bench_plateaus --runs 50 --seed 0",
        (_THERMAL_HEADER,),
        small=("benchmarks/bench_thermal.py", "plateaus", "--out", "{tmp}", "--runs", "1", "--bp-epochs", "20")),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py rate --out /tmp/bench_rate --runs 50 --seed 0",
        (_THERMAL_HEADER,),
        small=("benchmarks/bench_thermal.py", "rate", "--out", "{tmp}", "--runs", "1", "--bp-epochs", "20")),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py pan --out /tmp/bench_pan --runs 50 --seed 0",
        (_THERMAL_HEADER,),
        small=("benchmarks/bench_thermal.py", "pan", "--out", "{tmp}", "--runs", "1", "--bp-epochs", "20"),
        needs=("pan_thermal/pan_etu_cold_chamber.csv.gz",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py plateaus --as-written --out /tmp/bench_plateaus --runs 5 "
        "--seed 0",
        (_THERMAL_HEADER,),
        small=("benchmarks/bench_thermal.py", "plateaus", "--as-written", "--out", "{tmp}", "--runs", "1",
               "--bp-epochs", "20")),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py rate --as-written --out /tmp/bench_rate --runs 5 --seed 0",
        (_THERMAL_HEADER,),
        why_not_small="the plateaus form's code path on the variant sensor's scenario (the plateaus small form runs "
                      "it); its source-form networks cost about 20 s of CPU even at 20 epochs"),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py pan --as-written --out /tmp/bench_pan --runs 10 --seed 0",
        (_THERMAL_HEADER,),
        small=("benchmarks/bench_thermal.py", "pan", "--as-written", "--out", "{tmp}", "--runs", "1", "--bp-epochs",
               "20"),
        needs=("pan_thermal/pan_etu_cold_chamber.csv.gz",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py gainbias --out /tmp/bench_gainbias",
        ("| fit | iterations | converged | gyro RMS, calibration set [°/s] | gyro RMS, held-out set [°/s] | CPU [s] |",),
        small=("benchmarks/bench_thermal.py", "gainbias", "--out", "{tmp}", "--iterations", "30")),
    TableGenerator(
        "OMP_NUM_THREADS=1 python benchmarks/bench_thermal.py verdict --out /tmp/bench_verdict",
        ("| recording | 10 s-mean RMS, polynomial alone [°/s] | with residual PSO-BP [°/s] (seeds #/#/#) "
         "| enable_psobp |",),
        small=("benchmarks/bench_thermal.py", "verdict", "--out", "{tmp}", "--recordings", "rate",
               "--bp-epochs", "20")),
    TableGenerator(
        "python benchmarks/bench_magpf.py --no-broad",
        ("| method | hard-iron err mean / worst [µT] | norm RMS clean mean / worst [%] "
         "| norm RMS measured mean / worst [%] |",),
        small=("benchmarks/bench_magpf.py", "--no-broad", "--seeds", "1")),
    TableGenerator(
        "python benchmarks/bench_magpf.py --no-sim",
        ("| trial | spread raw | spread with filter | heading without filter | heading with filter | change "
         "| changes declared | heading, filter adapting from the start (pf_hold_prior 0) "
         "| heading, batch ellipsoid fitted on the eval phase |",
         "| trial | spread raw | spread without filter | spread derived | spread hand-set | heading without "
         "filter | heading derived | change | changes declared | heading hand-set |"),
        small=("benchmarks/bench_magpf.py", "--no-sim", "--trials", "35"), needs=("broad",)),
    TableGenerator(
        "python benchmarks/magpf_ablation.py",
        ("| configuration | tumbling: hard-iron err mean / worst [µT] | tumbling: norm RMS clean mean / worst [%] "
         "| jump: hard-iron err mean / worst [µT] | jump: norm RMS clean mean / worst [%] "
         "| seeds with a change declared: tumbling (false) / jump |",),
        small=("benchmarks/magpf_ablation.py", "--seeds", "2", "--seconds", "10")),
    TableGenerator(
        "python benchmarks/magpf_ablation.py --source-sweep",
        ("| configuration | tumbling: hard-iron err mean / worst [µT] | tumbling: norm RMS clean mean / worst [%] "
         "| jump: hard-iron err mean / worst [µT] | jump: norm RMS clean mean / worst [%] "
         "| seeds with a change declared: tumbling (false) / jump |",),
        small=("benchmarks/magpf_ablation.py", "--source-sweep", "--seeds", "1", "--seconds", "10")),
    TableGenerator(
        "python benchmarks/pf_cost.py",
        ("| configuration | samples | µs/sample | × VQF |",),
        small=("benchmarks/pf_cost.py", "--seconds", "3", "--repeats", "1"), trains=True, needs=("broad",)),
    TableGenerator(
        "python benchmarks/bench_elm.py",
        ("| model | hidden nodes | train loss (norm. MSE) | field error RMS [µT] | heading RMS [°] | train time [s] |",
         "| nodes | plain incremental ELM | with back-tuning |",
         "| budget | schedule | hidden nodes mean / max | field error RMS [µT] mean / worst | "
         "heading RMS [°] mean / worst | train time [s] mean | diverged |",
         "| gd_learning_rate | hidden nodes mean | heading RMS [°] mean / worst | diverged |",
         "| trial | eval samples | without ELM [°] | ELM always on [°] | change [°] | gate | gated [°] | gated change [°] |"),
        small=("benchmarks/bench_elm.py", "--small")),
    TableGenerator(
        "imufmu bench methods sim/calibration.csv.gz --eval sim/eval_handheld.csv.gz --out bench/methods-sim",
        (METHODS_BENCH_HEADER,),
        small=_call("from training.bench.methods_bench import bench_methods; from training.data.io import write_imu_csv; "
                    "from training.main_job import SCENARIO_DIR; from training.simulator import load_scenario, simulate; "
                    "bench_methods([write_imu_csv(simulate(load_scenario(SCENARIO_DIR / 'variants' / "
                    "'diag_calibration_clean.toml')), '{tmp}/session.csv.gz')], '{tmp}/out', samples=2000)"),
        trains=True),
    TableGenerator(
        "OMP_NUM_THREADS=1 imufmu bench methods ../shared/data/broad/01_undisturbed_slow_rotation_A.csv.gz "
        "../shared/data/broad/02_undisturbed_slow_rotation_B.csv.gz "
        "--eval ../shared/data/broad/04_undisturbed_slow_rotation_with_breaks_A.csv.gz "
        "../shared/data/broad/33_disturbed_attached_magnet_2cm.csv.gz --out bench/methods-broad",
        (METHODS_BENCH_HEADER,),
        small=_call("from training.bench.bench import trial_paths; from training.bench.methods_bench import bench_methods; "
                    "bench_methods(trial_paths(['01']), '{tmp}', trial_paths(['04']), samples=6000)"),
        trains=True, needs=("broad",)),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/noise_recovery.py",
        (_NOISE_RECOVERY_HEADER,),
        small=("benchmarks/noise_recovery.py", "--hours", "0.25", "--minutes", "2", "--seeds", "0", "--grades",
               "mems_grade")),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python benchmarks/noise_recovery.py --limit",
        (_NOISE_LIMIT_HEADER,),
        small=("benchmarks/noise_recovery.py", "--limit", "--hours", "0.25", "--seeds", "0", "--grades", "mems_grade")),
    TableGenerator(
        "OMP_NUM_THREADS=1 .venv/bin/python -m training.noise.report ../shared/data/pan_thermal/pan_etu_cold_chamber.csv.gz",
        ("| figure | x | y | z |",),
        small=("-m", "training.noise.report", str(SHARED / "pan_thermal" / "pan_etu_cold_chamber.csv.gz")),
        needs=("pan_thermal/pan_etu_cold_chamber.csv.gz",)),
)


def generator(command: str) -> TableGenerator | None:
    """The registered generator of `command` (as the docs name it), None when none is."""
    return next((g for g in GENERATORS if g.command == command), None)


def normalised_header(header: str) -> str:
    """A header row with every number replaced by '#' (run counts and seeds vary with the input)."""
    return re.sub(r"\d+(\.\d+)?", "#", header.strip())


@dataclass(frozen=True)
class DocTable:
    """A Markdown table of a doc: file (relative to ROOT), line of its header row (1-based),
    the header row, and the paragraphs just above and just below it (the text that names its source)."""
    file: str
    line: int
    header: str
    above: tuple[str, ...]
    below: tuple[str, ...]


def _paragraph(lines: list[str], start: int, step: int) -> tuple[str, ...]:
    """The non-blank lines from `start` on in direction `step` (±1), after skipping blank lines."""
    k = start
    while 0 <= k < len(lines) and not lines[k].strip():
        k += step
    out = []
    while 0 <= k < len(lines) and lines[k].strip() and not lines[k].startswith("|"):
        out.append(lines[k])
        k += step
    return tuple(out[::step])


def tables(file: str, text: str) -> list[DocTable]:
    """Every Markdown table of `text` (runs of lines starting with '|' outside code fences)."""
    lines, found, fenced, k = text.splitlines(), [], False, 0
    while k < len(lines):
        if lines[k].startswith("```"):
            fenced = not fenced
        if fenced or not lines[k].startswith("|"):
            k += 1
            continue
        end = k
        while end < len(lines) and lines[end].startswith("|"):
            end += 1
        found.append(DocTable(file, k + 1, lines[k].strip(), _paragraph(lines, k - 1, -1), _paragraph(lines, end, 1)))
        k = end
    return found


def source_problem(table: DocTable) -> str | None:
    """None when the table names its source as the module docstring says; else the problem."""
    context = "\n".join(table.above + table.below)
    if HAND_WRITTEN_TAG.search("\n".join(table.above)) or GENERATED_TAG in "\n".join(table.above):
        return None
    commands = COMMAND_TAG.findall(context)
    if not commands:
        return ("names no source: add `Command: `…`` (a command of training/bench/doc_tables.py GENERATORS) "
                "or `<!-- hand-written: <why> -->` just above it")
    known = [g for g in map(generator, commands) if g is not None]
    if not known:
        return f"names {', '.join(commands)}, which is not in training/bench/doc_tables.py GENERATORS"
    if not any(normalised_header(table.header) == normalised_header(h) for g in known for h in g.headers):
        return f"its header is not one that {', '.join(g.command for g in known)} prints (GENERATORS headers)"
    return None


def coverage_problems(root: Path = ROOT) -> list[str]:
    """'file:line: problem' for every table of DOC_FILES (PENDING_DOCS left out) without its source."""
    problems = []
    for file in DOC_FILES:
        if file in PENDING_DOCS:
            continue
        for table in tables(file, (root / file).read_text()):
            problem = source_problem(table)
            if problem:
                problems.append(f"{file}:{table.line}: table '{table.header[:60]}' {problem}")
    return problems
