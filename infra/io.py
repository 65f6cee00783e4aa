"""Files in and out: inputs read with named errors, outputs written atomically.

Reading (``read_text``, ``read_json``): a path that is missing, a folder, a device, unreadable,
too large, binary, UTF-16 or not UTF-8 raises ``ReadError`` naming the file and the problem
(a UTF-8 byte-order mark is accepted). JSON is parsed strictly: ``NaN``, ``Infinity``,
numbers that overflow a float and documents nested deeper than ``MAX_JSON_DEPTH`` are
refused, so no non-finite number (or recursion bomb) enters a run from a file.

Writing (``atomic_write*``): a result is either absent or complete, never half-written. The
data go to a hidden temporary file beside the target (``partial_path``), which is renamed into
place; SIGINT/SIGTERM arriving meanwhile are held until the rename is done, so Ctrl-C never
leaves a torn file (or a zipfile error). A write that fails raises ``OutputError`` naming the
file. Temporary files of a killed run match ``PARTIAL_GLOB`` and are removed by
``remove_partials`` (``infra.rundir`` does it when it takes a run folder).

``check_output_dir`` / ``check_output_file`` prove that an output place can be written, and
``check_free_space`` that the disk has room, before any long work starts.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import stat
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from infra.errors import InputError

MAX_INPUT_BYTES = 64 * 2**20
"""Largest text input read, bytes (chromosomes, gait tables, settings are a few kB; a larger
file is something else and is refused before it is read)."""
MAX_JSON_DEPTH = 64
"""Deepest nesting of lists and objects accepted in a JSON input (ours use 4 levels; deeper
documents would exhaust the recursion of code that walks them)."""
PARTIAL_MARK = ".partial"
"""Marks the temporary file of an output being written: ``.NAME.<random>.partial.SUFFIX``."""
PARTIAL_GLOB = f".*{PARTIAL_MARK}*"
"""Glob of such temporary files (hidden, so they never look like results)."""
_HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_PROCESS_START = time.time()
"""Before any file this process writes: older temporary files belong to earlier processes."""


class ReadError(InputError, ValueError):
    """An input file cannot be used; ``path`` and ``reason`` are kept for re-wrapping."""

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path, self.reason = Path(path), reason
        super().__init__(f"{path}: {reason}")


class OutputError(InputError, OSError):
    """An output place cannot be written (a file where a folder is needed, no permission,
    read-only or full disk, ...); the message names it."""


# --------------------------------------------------------------------------- reading


def read_bytes(path: str | Path, *, what: str, limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of the regular file ``path``, or ``ReadError`` naming it (missing, a folder,
    a device, no permission, larger than ``limit`` bytes)."""
    path = Path(path)
    try:
        st = path.stat()
        if stat.S_ISDIR(st.st_mode):
            raise ReadError(path, f"is a folder, not a {what}")
        if not (stat.S_ISREG(st.st_mode) or stat.S_ISFIFO(st.st_mode)):
            raise ReadError(path, f"is not a regular file, so not a {what}")
        if st.st_size > limit:
            raise ReadError(path, f"is {st.st_size:,} bytes, too large for a {what}")
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise ReadError(path, _unreadable(exc, what)) from exc
    if len(data) > limit:
        raise ReadError(path, f"is larger than {limit:,} bytes, too large for a {what}")
    return data


def _unreadable(exc: OSError, what: str) -> str:
    """Why a file could not be read, for ``ReadError``."""
    if isinstance(exc, FileNotFoundError):
        return f"no such {what}"
    if isinstance(exc, PermissionError):
        return f"cannot read this {what}: permission denied"
    return f"cannot read this {what}: {exc.strerror or exc}"


def decode_text(data: bytes, path: str | Path, *, what: str) -> str:
    """``data`` as UTF-8 text (a byte-order mark is dropped), or ``ReadError`` naming why not."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ReadError(path, f"is UTF-16 text; save the {what} as UTF-8")
    if b"\x00" in data:
        raise ReadError(path, f"holds binary data, not a {what} (text)")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        bad = data[exc.start]
        raise ReadError(
            path, f"is not UTF-8 text (byte 0x{bad:02x} at offset {exc.start}); not a {what}"
        ) from exc


def read_text(path: str | Path, *, what: str) -> str:
    """The UTF-8 text of ``path`` (BOM accepted), or ``ReadError`` naming the file."""
    return decode_text(read_bytes(path, what=what), path, what=what)


def _refuse_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} (only finite numbers are accepted)")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"number {text} is too large for a float")
    return value


def _depth(doc: Any) -> int:
    """Nesting depth of a parsed JSON document (iterative: any depth is safe)."""
    deepest, todo = 0, [(doc, 1)]
    while todo:
        node, d = todo.pop()
        if isinstance(node, dict | list):
            deepest = max(deepest, d)
            todo += [(v, d + 1) for v in (node.values() if isinstance(node, dict) else node)]
    return deepest


def parse_json(text: str, path: str | Path, *, what: str) -> Any:
    """Parse ``text`` as strict JSON (finite numbers only, at most ``MAX_JSON_DEPTH`` levels
    of nesting); ``ReadError`` naming ``path``."""
    try:
        doc = json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
    except json.JSONDecodeError as exc:
        raise ReadError(path, f"not valid JSON ({exc})") from exc
    except ValueError as exc:  # the hooks above, or an integer of too many digits
        raise ReadError(path, f"not a valid {what}: {exc}") from exc
    except RecursionError as exc:
        raise ReadError(path, f"not a valid {what}: nested too deeply") from exc
    if _depth(doc) > MAX_JSON_DEPTH:
        raise ReadError(path, f"not a valid {what}: nested more than {MAX_JSON_DEPTH} deep")
    return doc


def read_json(
    path: str | Path, *, what: str, error: Callable[[str], Exception] | None = None
) -> Any:
    """Parse the JSON file ``path`` (``read_text`` + ``parse_json``). Any problem raises
    ``ReadError`` naming the file, or ``error(message)`` when a caller wants its own type."""
    try:
        return parse_json(read_text(path, what=what), path, what=what)
    except ReadError as exc:
        if error is None:
            raise
        raise error(str(exc)) from exc


# --------------------------------------------------------------------------- writing


@contextmanager
def held_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while the block runs, then deliver them (main thread only;
    elsewhere a no-op). Keeps a short write whole instead of torn by Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    old = {s: signal.signal(s, lambda n, _f: got.append(n)) for s in _HELD_SIGNALS}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)
        for s in dict.fromkeys(got):
            signal.raise_signal(s)


def partial_path(path: str | Path) -> Path:
    """A unique hidden temporary name beside ``path`` that keeps its suffix (writers that pick
    a format by extension, matplotlib, numpy, rerun, behave as for ``path``)."""
    path = Path(path)
    return path.parent / f".{path.name}.{uuid.uuid4().hex[:12]}{PARTIAL_MARK}{path.suffix}"


def remove_partials(folder: str | Path, *, any_age: bool = False) -> list[Path]:
    """Delete the temporary files (``PARTIAL_GLOB``) that earlier, killed processes left in
    ``folder``; this process's own (newer than it, perhaps still being written) stay unless
    ``any_age``. Only call it while no other process writes there (``infra.rundir`` holds
    the lock)."""
    removed = []
    for p in Path(folder).glob(PARTIAL_GLOB):
        if p.is_file() and (any_age or p.stat().st_mtime < _PROCESS_START):
            p.unlink(missing_ok=True)
            removed.append(p)
    return removed


def _file_mode() -> int:
    """The mode a plain ``open()`` would create: 0666 less the umask."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def atomic_write(path: str | Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp_path)`` on a temporary file beside ``path``, then rename it into place.

    Signals are held meanwhile (``held_signals``); an ``OSError`` becomes ``OutputError``
    naming ``path``, and the temporary file is removed whatever happens.
    """
    path = Path(path)
    tmp = partial_path(path)
    created = False
    with held_signals():
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, _file_mode()))
            created = True
            write(tmp)
            os.replace(tmp, path)
        except OSError as exc:
            raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from exc
        finally:
            if created:
                tmp.unlink(missing_ok=True)
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    return atomic_write(path, lambda p: p.write_text(text, encoding="utf-8"))


def atomic_write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON to ``path`` atomically."""
    return atomic_write_text(path, json.dumps(obj, indent=2) + "\n")


def write_report(folder: Path, name: str, doc: Any, text: str) -> None:
    """A report pair in ``folder`` (created if needed): ``NAME.json`` (``doc``) and ``NAME.md``
    (``text``), each written atomically; then ``text`` on stdout."""
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / f"{name}.json", json.dumps(doc, indent=1))
    atomic_write_text(folder / f"{name}.md", text)
    print(text)


# --------------------------------------------------------------------------- output places


def _probe(folder: Path) -> None:
    """Create and delete a temporary file in ``folder`` (OSError if it cannot be written)."""
    fd, name = tempfile.mkstemp(prefix=".probe.", suffix=PARTIAL_MARK, dir=folder)
    os.close(fd)
    os.unlink(name)


def check_output_dir(path: str | Path, *, option: str = "--out") -> Path:
    """Create the output folder ``path`` if needed and prove it writable, else ``OutputError``
    naming ``option`` and the problem. Call it before any long work starts."""
    path = Path(path)
    try:
        if path.exists() and not path.is_dir():
            raise OutputError(f"{option} {path}: is a file, not a folder")
        missing = [d for d in (path, *path.parents) if not d.exists()]
        path.mkdir(parents=True, exist_ok=True)
        _CREATED.extend(d for d in missing if d not in _CREATED)
        _probe(path)
    except OutputError:
        raise
    except OSError as exc:
        raise OutputError(f"{option} {path}: cannot write there ({exc.strerror or exc})") from exc
    return path


_CREATED: list[Path] = []
"""The folders ``check_output_dir`` created since ``forget_created_folders()`` (a refused
command removes those it left empty: ``remove_created_folders``)."""


def forget_created_folders() -> None:
    """Start a command: no folder created yet."""
    _CREATED.clear()


def remove_created_folders() -> list[Path]:
    """Remove the folders ``check_output_dir`` created that are still empty (an empty, free
    ``.lock`` aside), deepest first, so that a command refused before any work leaves no
    empty ``--out`` behind; returns those removed."""
    removed = []
    for d in sorted(_CREATED, key=lambda d: -len(d.parts)):
        try:
            entries = list(d.iterdir())
            if any(e.name != ".lock" or not e.is_file() or e.stat().st_size for e in entries):
                continue
            for e in entries:
                e.unlink()
            d.rmdir()
            removed.append(d)
        except OSError:
            continue
    _CREATED.clear()
    return removed


def check_free_space(folder: str | Path, need_bytes: float, *, what: str) -> None:
    """``OutputError`` if the disk holding ``folder`` has less than ``need_bytes`` free."""
    free = shutil.disk_usage(folder).free
    if need_bytes > free:
        raise OutputError(
            f"{folder}: {what} need about {need_bytes / 1e6:,.0f} MB, only {free / 1e6:,.0f} MB "
            "are free there"
        )


def check_output_file(path: str | Path, *, option: str) -> Path:
    """Prove that the file ``path`` can be written: it is not a folder, its folder is created,
    and the temporary file an atomic write of it uses can be made there; else
    ``OutputError`` naming ``option``."""
    path = Path(path)
    check_output_dir(path.parent, option=f"{option} {path}: folder")
    try:
        if path.is_dir():
            raise OutputError(f"{option} {path}: is a folder, not a file")
        tmp = partial_path(path)
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        tmp.unlink()
    except OSError as exc:
        if isinstance(exc, OutputError):
            raise
        raise OutputError(f"{option} {path}: cannot write it ({exc.strerror or exc})") from exc
    return path


__all__ = [
    "MAX_INPUT_BYTES",
    "OutputError",
    "PARTIAL_GLOB",
    "ReadError",
    "atomic_write",
    "atomic_write_json",
    "atomic_write_text",
    "check_free_space",
    "check_output_dir",
    "check_output_file",
    "decode_text",
    "forget_created_folders",
    "held_signals",
    "write_report",
    "parse_json",
    "partial_path",
    "read_bytes",
    "read_json",
    "read_text",
    "remove_created_folders",
    "remove_partials",
]
