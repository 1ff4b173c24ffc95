"""The table of reference kinds (tests/reference_kinds.py) names every test function in tests/
exactly once, with a known kind: a test added, renamed or removed without its entry fails here."""

from reference_kinds import INDEPENDENT, KINDS, ORDER, collect, counts, markdown


def test_every_test_function_has_a_kind_and_every_kind_a_test_function():
    found = collect()
    assert len(found) == len(set(found)), "two test functions of one name in one module"
    missing = sorted(set(found) - set(KINDS))
    stale = sorted(set(KINDS) - set(found))
    assert not missing, "test functions without a kind in tests/reference_kinds.py:\n" + "\n".join(missing)
    assert not stale, "tests/reference_kinds.py names test functions that no longer exist:\n" + "\n".join(stale)


def test_every_kind_is_one_of_the_documented_ones():
    unknown = {name: kind for name, kind in KINDS.items() if kind not in ORDER}
    assert not unknown, f"kinds outside {ORDER}: {unknown}"
    assert INDEPENDENT == {"hand", "formula", "library", "golden"}


def test_the_collector_and_the_tables_on_a_made_up_folder(tmp_path):
    (tmp_path / "test_a.py").write_text(
        "def test_one():\n    pass\n\n"
        "async def test_two():\n    pass\n\n"
        "def helper():\n    pass\n\n"
        "class TestThing:\n    def test_three(self):\n        pass\n\n    def setup(self):\n        pass\n\n"
        "class Other:\n    def test_not_collected(self):\n        pass\n")
    (tmp_path / "helpers.py").write_text("def test_not_a_test_module():\n    pass\n")
    assert collect(tmp_path) == ["test_a.py::test_one", "test_a.py::test_two", "test_a.py::TestThing::test_three"]
    kinds = {"test_a.py::test_one": "hand", "test_a.py::test_two": "self", "test_b.py::test_x": "golden",
             "test_b.py::test_y": "smoke"}
    overall, per_module = counts(kinds)
    assert overall == {"hand": 1, "self": 1, "golden": 1, "smoke": 1}
    assert per_module["test_b.py"] == {"golden": 1, "smoke": 1}
    table = markdown(kinds)
    assert "| all | 4 | 1 |  |  | 1 |  | 1 | 1 | 2 (50 %) |" in table
    assert "| `test_a.py` | 2 | 1 |  |  |  |  | 1 |  | 1 (50 %) |" in table


def test_the_table_keeps_within_ruffs_line_length():
    """ruff (135 columns, in make test) checks it too; this says so to whoever edits the table
    and runs only this module: a long note goes on comment lines above its entry."""
    import reference_kinds

    long = [f"{n}: {len(line)}" for n, line in enumerate(open(reference_kinds.__file__).read().splitlines(), 1)
            if len(line) > 135]
    assert not long, "lines over 135 columns in tests/reference_kinds.py (move the note above its entry):\n" + "\n".join(long)
