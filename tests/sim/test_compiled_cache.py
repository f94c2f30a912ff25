"""``sim.compiled_cache``: numba's cache of the compiled modules goes when any of their sources
changes, and stays while none does."""

from __future__ import annotations

from pathlib import Path

from sim.compiled_cache import HASH_FILE, MODULES, cache_dir_of, drop_stale


def _cache(folder: Path, names: list[str]) -> None:
    folder.mkdir(exist_ok=True)
    for n in names:
        (folder / n).write_bytes(b"machine code")


def _setup(tmp_path: Path) -> tuple[Path, Path, list[str]]:
    src, cache = tmp_path / "sim", tmp_path / "sim" / "__pycache__"
    src.mkdir()
    (src / "compiled_step.py").write_text("def advance_in(): return 1\n")
    (src / "compiled_dynamic.py").write_text("def simulate_rows(): return 2\n")
    ours = ["compiled_step.advance_in-90.py311.nbi", "compiled_step.advance_in-90.py311.1.nbc",
            "compiled_dynamic.simulate_rows-122.py311.nbi",
            "compiled_dynamic.simulate_rows-122.py311.1.nbc"]
    return src, cache, ours


def test_a_changed_source_drops_every_compiled_modules_cache(tmp_path: Path) -> None:
    src, cache, ours = _setup(tmp_path)
    other = ["finger.cpython-311.pyc", "axis_kernel.simulate-10.py311.nbi"]
    assert drop_stale(src, cache, MODULES)  # a fresh clone: no hash yet, one written
    assert (cache / HASH_FILE).is_file()
    _cache(cache, ours + other)
    assert not drop_stale(src, cache, MODULES)  # nothing changed: the cache stays
    assert sorted(p.name for p in cache.iterdir() if p.name != HASH_FILE) == sorted(ours + other)
    # the step changes: the caller's cache (another file, unchanged itself) must go too
    (src / "compiled_step.py").write_text("def advance_in(): return 1.001\n")
    assert drop_stale(src, cache, MODULES)
    assert sorted(p.name for p in cache.iterdir() if p.name != HASH_FILE) == sorted(other)
    _cache(cache, ours)
    assert not drop_stale(src, cache, MODULES)  # the new hash was kept
    assert all((cache / n).is_file() for n in ours)


def test_a_touched_but_unchanged_source_keeps_the_cache(tmp_path: Path) -> None:
    src, cache, ours = _setup(tmp_path)
    drop_stale(src, cache, MODULES)
    _cache(cache, ours)
    f = src / "compiled_dynamic.py"
    f.write_text(f.read_text())  # a new modification time, the same content
    assert not drop_stale(src, cache, MODULES)
    assert all((cache / n).is_file() for n in ours)


def test_the_kernel_module_checks_numbas_own_cache_folder() -> None:
    import sim.compiled_kernel as kernel

    where = cache_dir_of(kernel.motor_friction)
    assert where is not None and where.name == "__pycache__"
    assert (where / HASH_FILE).is_file()  # written when the kernel module was imported
    assert set(MODULES) >= {p.stem for p in Path(kernel.__file__).parent.glob("compiled_*.py")
                            if p.stem != "compiled_cache"}
