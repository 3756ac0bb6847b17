"""One variable table (contract/variables.py): every list derived from it is current, and no
published value reference ever changes (issue 17 item 1)."""
from __future__ import annotations

from pathlib import Path

from contract.generate import REGIONS, stale
from contract.variables import VARIABLES

#: The value references published so far, one 'name vr' per line: an FMU user's saved setups and
#: connections refer to them, so a later table may add variables but never renumber these.
PUBLISHED = Path(__file__).resolve().parent / "golden" / "value_references.txt"


def test_every_generated_region_is_current():
    assert stale() == [], "run: python -m contract.generate"


def test_value_references_are_unique_and_contiguous():
    assert sorted(v.value_reference for v in VARIABLES) == list(range(len(VARIABLES)))
    assert len({v.name for v in VARIABLES}) == len(VARIABLES)


def test_no_published_value_reference_changes():
    published = dict(line.split() for line in PUBLISHED.read_text().splitlines())
    table = {v.name: str(v.value_reference) for v in VARIABLES}
    assert {name: table.get(name) for name in published} == published


def test_a_stale_region_is_found(tmp_path):
    """stale() reads the files: a region edited by hand is reported (the check can fail)."""
    root = Path(__file__).resolve().parent.parent
    for path in REGIONS:
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text((root / path).read_text())
    edited = (tmp_path / "sources/config.h").read_text().replace("vr_gyr_y = 1", "vr_gyr_y = 0")
    (tmp_path / "sources/config.h").write_text(edited)
    assert stale(tmp_path) == ["sources/config.h"]
    sensor = (tmp_path / "sources/sensor/config.h").read_text().replace("vr_gyr_x = 18", "vr_gyr_x = 17")
    (tmp_path / "sources/sensor/config.h").write_text(sensor)
    assert stale(tmp_path) == ["sources/config.h", "sources/sensor/config.h"]
