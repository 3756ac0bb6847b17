"""`imufmu campaign`: Monte-Carlo co-simulation of the FMU on Dask.

Truth: a serial loop over the same runs in this process (the acceptance of issue 19: 1 000 runs on a
LocalCluster equal to it bit for bit), and a fresh FMU instance per run for the reset the
partitions rely on. The errors are against the simulated recording's exact truth.
"""
import csv

import numpy as np
import pytest

from fmu.cosim import run_fmu
from fmu.packer import fmu_aux_columns
from training.cli import main
from training.data.io import read_imu_csv, write_imu_csv
from training.fleet.campaign import (CAMPAIGN_METRICS, PARTITIONS_PER_WORKER, ROW_VALUE_BYTES, CampaignError,
                                     campaign_runs, check_size, parse_variation, partitions, result_bytes, run_draws,
                                     run_partition)
from training.main_job import recording_parameters
from training.simulator import simulate_to_dir

#: Runs of the acceptance test; samples of its recording (1 s at 100 Hz keeps 2 000 co-simulations short).
RUNS, SAMPLES = 1000, 100
VARIATIONS = ("noise_gyr=uniform(0,0.01)", "noise_mag=normal(0.3,0.1)", "declination=normal(0.05,0.01)",
              "attitude_mode=choice(0,1)")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """The first SAMPLES samples of the simulated handheld scenario, with truth."""
    from pathlib import Path
    root = Path(__file__).resolve().parent.parent
    folder = tmp_path_factory.mktemp("campaign")
    full = read_imu_csv(simulate_to_dir(root / "scenarios" / "eval_handheld.toml", folder, seed=3))
    return write_imu_csv(full.slice(slice(0, SAMPLES)), folder / "short.csv.gz")


def test_a_thousand_runs_on_a_local_cluster_equal_a_serial_loop(identity_fmu2, recording):
    from distributed import LocalCluster
    variations = tuple(parse_variation(v) for v in VARIATIONS)
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None, processes=True) as cluster:
        distributed_runs = campaign_runs(identity_fmu2, recording, RUNS, variations, seed=5,
                                         scheduler=cluster.scheduler_address, progress=False)
    serial = run_partition(list(range(RUNS)), str(identity_fmu2), str(recording), variations, 5)
    assert [r["run"] for r in distributed_runs] == list(range(RUNS))
    assert distributed_runs == serial  # every drawn value and every error, bit for bit
    assert len({r["declination"] for r in serial}) == RUNS and {r["attitude_mode"] for r in serial} == {0.0, 1.0}
    assert all(np.isfinite(r[m]) for r in serial for m in ("rate_err_dps", "tilt_err_deg"))


def test_a_reset_instance_gives_what_a_fresh_one_gives(identity_fmu3, recording):
    variations = tuple(parse_variation(v) for v in VARIATIONS)
    data = read_imu_csv(recording)
    runs = run_partition([0, 1, 2], str(identity_fmu3), str(recording), variations, 9)
    from training.evaluate import compute_metrics
    from training.fleet.campaign import _mounting
    from training.mounting import body_references
    for row in runs:
        parameters, _, noise = run_draws(variations, 9, row["run"], len(data))
        parameters = {**recording_parameters(data), **parameters}
        out = run_fmu(identity_fmu3, data.t, data.inputs(fmu_aux_columns(identity_fmu3)) + noise, parameters)
        fresh = compute_metrics(out, body_references(data, _mounting(str(identity_fmu3), parameters))).as_dict()
        assert {m: row[m] for m in CAMPAIGN_METRICS} == {m: fresh[m] for m in CAMPAIGN_METRICS}


def test_input_noise_raises_the_rate_error_it_adds(identity_fmu2, recording):
    """σ of white noise on the gyro input adds σ (in quadrature) to the rate error: with 0.05 rad/s
    the error is at least 2.5 °/s (0.05 rad/s = 2.9 °/s; 100 samples: ±15 % sampling spread)."""
    quiet, noisy = (run_partition([0], str(identity_fmu2), str(recording), (parse_variation(v),), 1)[0]
                    for v in ("noise_gyr=choice(0)", "noise_gyr=choice(0.05)"))
    assert noisy["rate_err_dps"] > 2.5 and quiet["rate_err_dps"] < noisy["rate_err_dps"] / 2


@pytest.mark.parametrize("text, problem", [("nope=normal(0,1)", "neither an FMU parameter"),
                                           ("rate_x=normal(0,1)", "not a parameter"),
                                           ("declination=gauss(0,1)", "unknown distribution"),
                                           ("declination=normal(0,-1)", "SIGMA ≥ 0"),
                                           ("declination=uniform(1)", "takes 2"),
                                           ("declination", "expected NAME=")])
def test_bad_variations_are_named(text, problem):
    with pytest.raises(CampaignError, match=problem):
        parse_variation(text)


def test_cli_writes_the_campaign_report(identity_fmu2, recording, tmp_path, capsys):
    assert main(["campaign", str(identity_fmu2), str(recording), "--runs", "6", "--vary", "noise_acc=uniform(0,0.1)",
                 "--out", str(tmp_path), "--workers", "1"]) == 0
    md = (tmp_path / "campaign.md").read_text()
    assert md.startswith("# Campaign: 6 runs") and "| tilt_err_deg | 6 |" in md
    assert (tmp_path / "runs.csv").read_text().count("\n") == 7 and (tmp_path / "campaign.png").is_file()


@pytest.mark.parametrize("runs, workers", [(1, 2), (7, 2), (1000, 3), (10 ** 12, 2)])
def test_partitions_cover_every_run_once_in_ranges_whose_size_does_not_grow_with_the_runs(runs, workers):
    parts = partitions(runs, workers)
    assert all(isinstance(p, range) for p in parts) and len(parts) == min(runs, workers * PARTITIONS_PER_WORKER)
    assert parts[0].start == 0 and parts[-1].stop == runs
    assert all(a.stop == b.start for a, b in zip(parts, parts[1:]))


def test_a_campaign_larger_than_memory_is_refused_up_front_with_the_estimate(identity_fmu2, recording, tmp_path, capsys):
    """Issue 31 item 3: --runs 1000000000 built every run index before any work (4.3 GB in 12 s). The
    refusal comes before any cluster starts; the estimate is the measured bytes per value."""
    variations = (parse_variation("noise_gyr=uniform(0,0.01)"),)
    need = result_bytes(10 ** 9, variations)
    assert need == 10 ** 9 * ROW_VALUE_BYTES * (3 + len(CAMPAIGN_METRICS))
    with pytest.raises(CampaignError, match=r"--runs 1000000000: the results would take about 640 GB"):
        check_size(10 ** 9, variations, free=16 * 10 ** 9)
    check_size(1000, variations, free=16 * 10 ** 9)  # 640 kB: accepted
    check_size(10 ** 9, variations, free=None)       # unknown free memory: not refused
    assert main(["campaign", str(identity_fmu2), str(recording), "--runs", "1000000000000", "--vary",
                 "noise_gyr=uniform(0,0.01)", "--out", str(tmp_path / "c"), "--workers", "1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the results would take about" in err[0] and not (tmp_path / "c").exists()


@pytest.mark.parametrize("text, problem", [
    ("noise_gyr=uniform(-1e308,1e308)", "HIGH − LOW must be a finite number"),
    ("declination=uniform(0,10)", r"declination must stay in \[-3.14159, 3.14159\]"),
    ("tau_acc=choice(0,3)", r"tau_acc must stay in \(0, 86400\]"),
    ("field_norm=normal(2,1)", r"field_norm must stay in \[5, 1000\]"),
    ("noise_gyr=normal(-1,0.1)", r"noise_gyr must stay in \[0, 100\] \(the input's plausibility limit\)"),
    ("noise_acc=uniform(0,1e300)", r"noise_acc must stay in \[0, 2000\]"),
    ("enable_pf=choice(0,0.5)", "enable_pf is a Boolean parameter: vary it as choice"),
    ("pf_particles=uniform(64,128)", "pf_particles is an Integer parameter: vary it as choice"),
])
def test_variations_that_draw_outside_a_parameters_range_are_refused_up_front(text, problem):
    """Issue 31 item 7: such draws were checked only inside the workers (one bad draw aborted the
    campaign with Dask's dump; uniform(-1e308, 1e308) was an OverflowError traceback)."""
    with pytest.raises(CampaignError, match=problem):
        parse_variation(text)


def test_a_run_whose_draw_the_fmu_refuses_fails_alone_with_its_reason(identity_fmu2, recording, tmp_path, capsys):
    """tau_acc = normal(0.3, 1): about 38 % of the draws are ≤ 0, which the FMU refuses at initialisation.
    Those runs are failed rows with their reason, the others complete, the report says how many
    failed, and the exit status is EXIT_PARTIAL."""
    from training.completeness import EXIT_PARTIAL
    assert main(["campaign", str(identity_fmu2), str(recording), "--runs", "12", "--vary", "tau_acc=normal(0.3,1)",
                 "--out", str(tmp_path), "--workers", "1"]) == EXIT_PARTIAL
    rows = list(csv.DictReader((tmp_path / "runs.csv").open()))
    failed = [r for r in rows if r["failed"]]
    assert 0 < len(failed) < 12 and all(float(r["tau_acc"]) <= 0 for r in failed)
    assert all(float(r["tau_acc"]) > 0 and np.isfinite(float(r["tilt_err_deg"])) for r in rows if not r["failed"])
    assert f"{len(failed)} of 12 runs failed" in (tmp_path / "campaign.md").read_text()
    last = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress bar
    assert last.startswith("imufmu campaign: ") and "tau_acc must be finite and within (0, 86400] s" in last
    assert last.endswith(f"exit status {EXIT_PARTIAL}")


def test_a_recording_without_any_reference_is_refused(identity_fmu2, recording, tmp_path, capsys):
    """It exited 0 with an all-NaN runs.csv."""
    from training.data.reference_source import strip_references
    bare = write_imu_csv(strip_references(read_imu_csv(recording)), tmp_path / "bare.csv.gz")
    assert main(["campaign", str(identity_fmu2), str(bare), "--runs", "2", "--out", str(tmp_path / "c"),
                 "--workers", "1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bare.csv.gz: no reference" in err[0]


def test_the_unit_is_varied_like_any_parameter(identity_fmu2, recording, tmp_path):
    """Issue 32: `--vary unit=FLEET_DIR` draws one of a fleet's units per run and sets its calibration.ssv in
    the FMU (built without a calibration): each run equals a fresh run with that unit's coefficients and
    settings, and units that differ give different errors."""
    from contract.layout import OFFSET_THERMAL, identity_coefficients
    from fmu.calibration_file import write_calibration
    from training.evaluate import compute_metrics
    from training.fleet.campaign import _mounting
    from training.mounting import body_references
    units = []
    for k, gain in enumerate((1.0, 1.03, 0.97)):  # three units: their gyro gain differs by ±3 %
        coefficients = np.array(identity_coefficients())
        coefficients[OFFSET_THERMAL + 4] = coefficients[OFFSET_THERMAL + 8] = coefficients[OFFSET_THERMAL + 12] = gain
        (tmp_path / "fleet" / f"unit{k}").mkdir(parents=True)
        write_calibration(tmp_path / "fleet" / f"unit{k}" / "calibration.ssv", coefficients, {"declination": 0.01 * k})
        units.append(coefficients)
    (tmp_path / "fleet" / "fleet.md").write_text("not a unit")
    variation = parse_variation(f"unit={tmp_path / 'fleet'}")
    assert len(variation.units) == 3 and "3 units" in variation.text()
    rows = run_partition(range(8), str(identity_fmu2), str(recording), (variation,), 4)
    assert {row["unit"] for row in rows} == {0.0, 1.0, 2.0}
    data = read_imu_csv(recording)
    for row in rows[:4]:
        k = int(row["unit"])
        parameters = {"declination": 0.01 * k, **recording_parameters(data)}
        out = run_fmu(identity_fmu2, data.t, data.inputs(), parameters, coefficients=units[k])
        fresh = compute_metrics(out, body_references(data, _mounting(str(identity_fmu2), parameters))).as_dict()
        assert {m: row[m] for m in CAMPAIGN_METRICS} == {m: fresh[m] for m in CAMPAIGN_METRICS}
    assert len({row["rate_err_dps"] for row in rows}) == 3  # one error per unit
    with pytest.raises(CampaignError, match="no unit of"):
        parse_variation(f"unit={tmp_path}")
