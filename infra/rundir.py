"""A run folder belongs to one run: an OS lock, an ownership record, and ``--force``.

``run_folder(folder, settings, owned=...)`` is the context manager every command that writes
into a folder runs inside. Before anything in the folder is touched it

1. proves the folder writable (``infra.io.check_output_dir``);
2. takes an exclusive OS lock on ``folder/.lock`` (``fcntl.flock``; the OS releases it when
   the process ends, however it ends, SIGKILL included), so a second writer is refused with
   a message naming the holder;
3. removes the temporary files a killed writer left in the folders the run writes
   (``infra.io.remove_partials``);
4. compares the folder's ownership record (``settings.json``: the settings the run was made
   with) with this run's settings:

   - no record and none of the run's files (``owned`` globs): a new run; the record is written;
   - the same settings: with ``resume`` (or for a command that cannot resume, which simply
     redoes its outputs) the run goes on; a resumable command without ``resume`` is refused,
     so that finished work is never overwritten by accident;
   - other settings, or run files without a record: refused, naming the differing settings;
   - a record that cannot be read (not JSON, not an object): refused, naming the file;
   - a record of another command (its ``command`` field; ``run_folder(..., command=...)``
     writes it): refused, naming that command, **also with ``force``**: ``force`` deletes
     only this command's own files, so it would mix the two runs' files in one folder. A
     record without ``command`` (written before commands were recorded) is an unknown
     command: its folder is judged by this run's own files, as before.

   ``force`` starts afresh instead: it deletes only the files that match ``owned`` (and
   folders left empty by that), never anything else in the folder.

The lock is held until the block ends. If the block ends with an exception (Ctrl-C
included), the temporary files of the run's unfinished writes are removed before the lock is
released; the caller must have stopped its writers by then (``infra.executors`` terminates
its workers on the way out). Locks are POSIX (Linux, macOS); where ``fcntl`` does
not exist the folder is used unlocked.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from infra.errors import InputError
from infra.io import ReadError, atomic_write_json, check_output_dir, read_json, remove_partials

RECORD_FILE = "settings.json"
"""A run folder's ownership record: the settings the run in it was made with."""
COMMAND_KEY = "command"
"""The ownership record's field naming the command whose run the folder holds."""
LOCK_FILE = ".lock"
"""The file a running command holds an OS lock on (never deleted; names the holder while
held, empty otherwise)."""
_MAX_DIFFS = 4


class RunDirError(InputError, RuntimeError):
    """A run folder cannot be used: in use by another process, or holding another run."""


@dataclass(frozen=True)
class Claim:
    """A run folder taken by this process; ``state`` is how it was found."""

    folder: Path
    state: str
    """``"new"``, ``"resumed"`` (same settings, continued or redone) or ``"forced"``."""


@contextmanager
def folder_lock(folder: Path, *, option: str = "--out") -> Iterator[None]:
    """Hold the exclusive OS lock of ``folder`` for the block, else ``RunDirError``."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
            raise RunDirError(
                f"{folder} is in use by another run ({holder}); wait for it to finish, or "
                f"use another {option}"
            ) from None
        os.ftruncate(fd, 0)
        now = dt.datetime.now().isoformat(timespec="seconds")
        os.pwrite(fd, f"pid {os.getpid()} since {now}\n".encode(), 0)
        try:
            yield
        finally:
            os.ftruncate(fd, 0)  # an empty lock file: nobody holds it
    finally:
        os.close(fd)  # releases the lock


def owned_files(folder: Path, owned: Sequence[str]) -> list[Path]:
    """The files under ``folder`` matching the ``owned`` globs (relative to it)."""
    found = {p for pattern in owned for p in folder.glob(pattern) if p.is_file()}
    return sorted(found)


def _owned_dirs(folder: Path, owned: Sequence[str]) -> set[Path]:
    """``folder`` and the existing subfolders that ``owned`` globs reach into."""
    subs = {str(Path(p).parent) for p in owned if Path(p).parent != Path(".")}
    return {folder} | {d for s in subs for d in folder.glob(s) if d.is_dir()}


def clear_owned(folder: Path, owned: Sequence[str]) -> list[Path]:
    """Delete the files matching ``owned`` and the subfolders this leaves empty."""
    files = owned_files(folder, owned)
    for p in files:
        p.unlink(missing_ok=True)
    for d in sorted({p.parent for p in files}, key=lambda d: -len(d.parts)):
        while d != folder and d.is_dir() and not any(d.iterdir()):
            d.rmdir()
            d = d.parent
    return files


def settings_diff(have: Any, want: Any, prefix: str = "") -> list[str]:
    """Readable differences between two JSON documents (``key: A there, B here``)."""
    if isinstance(have, dict) and isinstance(want, dict):
        out: list[str] = []
        for k in sorted(set(have) | set(want), key=str):
            out += settings_diff(have.get(k), want.get(k), f"{prefix}{k}.")
        return out
    if have == want:
        return []

    def short(v: Any) -> str:
        s = json.dumps(v) if v is not None else "absent"
        return s if len(s) <= 40 else s[:37] + "..."

    return [f"{prefix.rstrip('.') or 'settings'}: {short(have)} there, {short(want)} here"]


def _refuse(folder: Path, why: str, option: str) -> RunDirError:
    return RunDirError(
        f"{folder} {why}; nothing in it was changed. Use another {option}, or add --force to "
        "delete that run's files (only those) and start afresh"
    )


def record_of(settings: Mapping[str, Any], command: str | None) -> dict[str, Any]:
    """The ownership record a run with ``settings`` of ``command`` writes: the settings as
    JSON, with ``command`` first (when given)."""
    doc = json.loads(json.dumps(settings))
    return doc if command is None else {COMMAND_KEY: command} | doc


def record_command(have: Any) -> str | None:
    """The command named by an ownership record (None: not recorded, an older record)."""
    cmd = have.get(COMMAND_KEY) if isinstance(have, dict) else None
    return cmd if isinstance(cmd, str) else None


def _take(
    folder: Path, settings: Any, owned: Sequence[str], resume: bool, resumable: bool, force: bool,
    option: str, command: str | None = None,
) -> str:  # fmt: skip
    """Check the ownership record against ``settings``; returns the claim's state."""
    want = record_of(settings, command)
    record = folder / RECORD_FILE
    files = [p for p in owned_files(folder, owned) if p != record]
    have: Any = None
    bad = None  # why the record cannot be read
    if record.exists():
        try:
            have = read_json(record, what="run settings record")
        except ReadError as exc:
            bad = exc.reason
        if bad is None and not isinstance(have, dict):
            bad = f"not a settings object but a JSON {type(have).__name__}"
    theirs = record_command(have)
    if command is not None and theirs is not None and theirs != command:
        raise RunDirError(
            f"{folder} holds a 'servobot {theirs}' run ({record} says so), not a 'servobot "
            f"{command}' one; nothing in it was changed. Use another {option} (--force cannot "
            f"take over another command's folder: it deletes only {command}'s own files and "
            "would mix the two runs)"
        )
    if isinstance(have, dict) and theirs is None and command is not None:
        want = record_of(settings, None)  # an older record, without a command: compare as before
    if bad is not None:
        if force:
            clear_owned(folder, [*owned, RECORD_FILE])
            return "forced"
        raise _refuse(
            folder, f"has an ownership record that cannot be read ({record}: {bad}), so whose "
            "run it holds is unknown", option,
        )  # fmt: skip
    if force and (files or (have is not None and have != want)):
        clear_owned(folder, [*owned, RECORD_FILE])
        return "forced"
    if not files:
        return "new"
    if have is None:
        raise _refuse(folder, f"holds run files but no {RECORD_FILE} (an unknown run)", option)
    if have != want:
        diff = settings_diff(have, want)
        more = f" and {len(diff) - _MAX_DIFFS} more" if len(diff) > _MAX_DIFFS else ""
        detail = "; ".join(diff[:_MAX_DIFFS]) + more
        raise _refuse(folder, f"holds a run made with other settings ({detail})", option)
    if resumable and not resume:
        raise RunDirError(
            f"{folder} already holds this run (same settings); add --resume to continue it, or "
            "--force to delete its files and start afresh"
        )
    return "resumed"


@contextmanager
def run_folder(
    folder: str | Path,
    settings: Mapping[str, Any],
    *,
    owned: Sequence[str],
    resume: bool = False,
    resumable: bool = True,
    force: bool = False,
    option: str = "--out",
    command: str | None = None,
) -> Iterator[Claim]:
    """Take ``folder`` for a run with ``settings`` (a JSON-able mapping) for the block.

    ``owned``: globs (relative to ``folder``) of every file the run writes; ``resumable``:
    whether the command can continue a run (``resume``) or only redo it; ``option`` names
    the folder's command-line option in messages; ``command`` (``"validate"``, ``"evolve
    coverage"``, ...) is recorded, and a folder recording another command is refused. See the
    module docstring for the rules.
    Raises ``RunDirError`` (or ``infra.io.OutputError``) before touching anything.
    """
    folder = check_output_dir(folder, option=option)
    with folder_lock(folder, option=option):
        for d in _owned_dirs(folder, owned):
            remove_partials(d)
        state = _take(folder, settings, owned, resume, resumable, force, option, command)
        atomic_write_json(folder / RECORD_FILE, record_of(settings, command))
        try:
            yield Claim(folder, state)
        except BaseException:  # the run's writers have stopped: drop their temporary files
            for d in _owned_dirs(folder, owned):
                remove_partials(d, any_age=True)
            raise


__all__ = [
    "COMMAND_KEY",
    "LOCK_FILE",
    "RECORD_FILE",
    "Claim",
    "RunDirError",
    "clear_owned",
    "folder_lock",
    "owned_files",
    "record_command",
    "record_of",
    "run_folder",
    "settings_diff",
]
