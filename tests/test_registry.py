"""Registries are the single source of names: --help, case-file validation, docs tables."""

from pathlib import Path

import pytest

from signorini.dynamics.model.mass import MASS_VARIANTS, mass_matrix
from signorini.dynamics.schemes import SCHEMES
from signorini.errors import InputError
from signorini.io.cli import build_parser
from signorini.io.config import load_case
from signorini.io.doctables import all_registries, render
from signorini.linalg import BACKENDS
from signorini.registry import Parameter, Registry

ROOT = Path(__file__).parents[1]
BASE = (ROOT / "examples" / "bar2d.toml").read_text()


def _run_help() -> str:
    import os
    from unittest import mock

    with mock.patch.dict(os.environ, {"COLUMNS": "100000"}):  # no wrapping inside hyphenated names
        p = build_parser()
        sub = next(a for a in p._actions if a.dest == "command")
        return " ".join(sub.choices["run"].format_help().split())


def test_docs_table_is_generated_and_up_to_date():
    assert (ROOT / "docs" / "registries.md").read_text() == render(), "run python -m signorini.io.doctables --write"


@pytest.mark.parametrize("title", list(all_registries()))
def test_every_name_in_help_and_docs(title):
    reg = all_registries()[title]
    help_text, doc = _run_help(), render()
    for entry in reg:
        assert f"`{entry.name}`" in doc
        if reg in (SCHEMES, MASS_VARIANTS, BACKENDS):
            assert entry.name in help_text, entry.name


@pytest.mark.parametrize("name", SCHEMES.names())
def test_every_scheme_name_accepted_by_case_files(tmp_path, name):
    case = tmp_path / "c.toml"
    case.write_text(BASE.replace('scheme = "crank-nicolson"', f'scheme = "{name}"'))
    assert load_case(case).scheme == SCHEMES.resolve(name)


@pytest.mark.parametrize("name", MASS_VARIANTS.names())
def test_every_mass_name_accepted_by_case_files(tmp_path, name):
    case = tmp_path / "c.toml"
    case.write_text(BASE.replace('mass = "seed"', f'mass = "{name}"'))
    assert load_case(case).mass == name


def test_dummy_entries_appear_everywhere(tmp_path):
    from signorini.dynamics.schemes import Theta

    class Dummy(Theta):
        name = "dummy-scheme"
        description = "a dummy scheme registered at runtime"

    SCHEMES.register("dummy-scheme", Dummy, Dummy.description, ("dmy",), Dummy.parameters)
    MASS_VARIANTS.register("dummy-mass", MASS_VARIANTS.get("lumped").obj, "a dummy mass registered at runtime")
    try:
        assert "dummy-scheme (dmy)" in _run_help() and "dummy-mass" in _run_help()
        assert "`dummy-scheme`" in render() and "`dummy-mass`" in render()
        case = tmp_path / "c.toml"
        text = BASE.replace('scheme = "crank-nicolson"', 'scheme = "dmy"\ntheta = 0.75')
        case.write_text(text.replace('mass = "seed"', 'mass = "dummy-mass"'))
        c = load_case(case)
        assert (c.scheme, c.mass, c.scheme_options) == ("dummy-scheme", "dummy-mass", {"theta": 0.75})
    finally:
        SCHEMES.unregister("dummy-scheme")
        MASS_VARIANTS.unregister("dummy-mass")
    assert "dummy-scheme" not in _run_help()
    with pytest.raises(InputError, match="unknown time.scheme 'dmy'; allowed: crank-nicolson"):
        load_case(case)


def test_unknown_names_never_fall_through():
    from signorini.fem.mesh import interval

    with pytest.raises(InputError, match="unknown mass 'heavy'; allowed: standard, lumped, seed"):
        mass_matrix("heavy", interval(4), 1.0, [0])
    reg = Registry("widget")
    reg.register("a", 1, "first", ("aa",), (Parameter("k", 1.0, "a number", float, 0.0),))
    assert reg.get("AA").name == "a"
    with pytest.raises(InputError, match="'widget a.k' must satisfy 0.0 <= k"):
        reg.get("a").options({"k": -1}, where="widget a")
    with pytest.raises(ValueError, match="already registered"):
        reg.register("aa", 2, "clash")


@pytest.mark.parametrize("kind", [float, int])
def test_an_integer_beyond_double_precision_is_a_clear_input_error(kind):
    """TOML integers have no size limit: 10**400 as an option (found by the case fuzzer as
    ``time.stiffness``) is refused with the field's name, not an OverflowError."""
    p = Parameter("stiffness", kind(1), "a number", kind, 0)
    with pytest.raises(InputError, match=r"'time.stiffness' must be a finite number .* an integer of 401 digits"):
        p.convert(10**400, "time")
    assert p.convert(10**15, "time") == kind(10**15)


def test_every_backend_declares_its_traits_and_the_distributed_list_agrees():
    """Backends are registry entries with what they support (issue 39, item 4): the traits are
    there for every entry, a factor's entry names its Factor class, and the core layer's list
    of distributed backends (signorini.parallel, which cannot import linalg) is the traits'."""
    from signorini.linalg.base import BACKENDS, BackendTraits
    from signorini.parallel import DISTRIBUTED_BACKENDS

    for e in BACKENDS:
        assert isinstance(e.traits, BackendTraits), e.name
        assert e.traits.factor == isinstance(e.obj, str), e.name
        assert not (e.traits.factor and e.traits.iterative), e.name
    assert tuple(e.name for e in BACKENDS if e.traits.distributed) == DISTRIBUTED_BACKENDS
    assert [e.name for e in BACKENDS if e.traits.chooses] == ["auto"]
