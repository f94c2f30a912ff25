"""Numba's disk cache kept in step with every compiled source, not only a function's own file.

numba (0.68 here) keys a cached function on a hash of the file that defines it.  The compiled
finger's functions call, and inline, functions of the other compiled modules
(``simulate_rows`` in ``sim/compiled_dynamic.py`` inlines the step of
``sim/compiled_step.py``; the hand loop in ``sim/compiled_runs.py`` links it), so after an
edit of the step the callers would load their old machine code and run the old physics,
silently.  Measured 2026-11-28: a probe edit of ``advance_in`` (its ``dt`` scaled by 1.001)
left a 60 s diagnosis simulation bit for bit unchanged, before and after touching
``compiled_dynamic.py`` (the key is the file's content, not its time), until the cache files
were removed.

:func:`drop_stale` hashes the sources of every module whose functions numba compiles
together here (:data:`MODULES`) and compares the hash with the one it wrote beside the cache
last time; when they differ it removes those modules' cache files, so every function
compiles afresh once, and writes the new hash.  :mod:`sim.compiled_kernel`, which every
compiled module imports before any of its functions can be called (numba loads a cached
function at its first call), runs it once at import.  Two processes that find the same
stale cache both remove it; at worst a function compiles twice.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

#: the modules of ``sim/`` whose numba functions call into each other (their file stems)
MODULES = ("compiled_kernel", "compiled_crush", "compiled_step", "compiled_runs",
           "compiled_dynamic", "compiled_weight", "bench_compiled")
#: the file beside the cache holding the sources' hash
HASH_FILE = "compiled_sources.sha256"


def sources_hash(files: Iterable[Path]) -> str:
    """SHA-256 over the files' names and contents, in the order given."""
    h = hashlib.sha256()
    for f in files:
        h.update(f.name.encode())
        h.update(b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def drop_stale(source_dir: Path, cache_dir: Path, modules: tuple[str, ...] = MODULES
               ) -> bool:
    """Remove the cache files of ``modules`` (``<stem>.*.nbi`` / ``.nbc`` in ``cache_dir``)
    when their sources in ``source_dir`` changed since the hash in ``cache_dir`` was
    written; write the new hash.  True when the hash changed (files removed or not)."""
    files = [source_dir / f"{m}.py" for m in modules if (source_dir / f"{m}.py").is_file()]
    digest = sources_hash(files)
    stamp = cache_dir / HASH_FILE
    try:
        if stamp.read_text().strip() == digest:
            return False
    except OSError:
        pass  # no hash yet (a fresh clone) or unreadable: treat the cache as stale
    for m in modules:
        for old in (*cache_dir.glob(f"{m}.*.nbi"), *cache_dir.glob(f"{m}.*.nbc")):
            old.unlink(missing_ok=True)  # (another process may have removed it first)
    tmp = cache_dir / f"{HASH_FILE}.{os.getpid()}"
    try:
        # on a fresh clone numba has not made its folder yet: the hash must be there before
        # the first save, or the next process would drop what this one compiles
        cache_dir.mkdir(parents=True, exist_ok=True)
        tmp.write_text(digest + "\n")
        os.replace(tmp, stamp)
    except OSError:
        pass  # a read-only cache folder: numba will not save there either
    return True


def cache_dir_of(dispatcher: object) -> Path | None:
    """The folder numba caches ``dispatcher``'s machine code in (None when it has none)."""
    cache = getattr(dispatcher, "_cache", None)
    path = getattr(cache, "_cache_path", None)
    return Path(path) if path else None
