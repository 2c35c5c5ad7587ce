"""``Settings`` is the one reader of the ``SOFTEVO_*`` environment and the one place a
setting's default is written: docs/cluster.md's table is the one ``settings_table()`` writes
from the fields, and no other package module names a setting's variable."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from softevo.service.settings import Settings, settings_table

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("sim", "evolution", "worker", "analysis", "service", "softevo")
# the worker layer sits below service: its job processes read the engine and device that
# ``softevo worker`` set from Settings (service/cli/service.py) into their environment
HANDED_DOWN = {"worker/evaluate.py": {"SOFTEVO_ENGINE", "SOFTEVO_DEVICE"}}


def test_the_docs_table_is_the_generated_one():
    docs = (ROOT / "docs" / "cluster.md").read_text(encoding="utf-8")
    assert settings_table() in docs, "regenerate it: python -m softevo.service.settings"


def test_every_setting_is_described_with_its_readers():
    for name, info in Settings.model_fields.items():
        assert info.description, name
        assert (info.json_schema_extra or {}).get("used_by"), name


def test_no_other_module_reads_a_setting_from_the_environment():
    variables = {f"SOFTEVO_{name.upper()}" for name in Settings.model_fields}
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            name = str(path.relative_to(ROOT))
            if name == "service/settings.py":
                continue
            named = set(re.findall(r"""["'](SOFTEVO_[A-Z_]+)["']""", path.read_text(encoding="utf-8")))
            extra = (named & variables) - HANDED_DOWN.get(name, set())
            if extra:
                found[name] = sorted(extra)
    assert not found, found


@pytest.mark.parametrize(("variable", "value"), [("SOFTEVO_PORT", "http"), ("SOFTEVO_ENGINE", "warp")])
def test_a_bad_value_is_one_user_error_naming_the_variable(monkeypatch, variable, value):
    from softevo.errors import UserError

    monkeypatch.setenv(variable, value)
    with pytest.raises(UserError, match=variable):
        Settings.load()
