"""Atomic output: every file hound-id writes appears whole or not at all.

Writers produce a temporary file beside the target and ``os.replace`` it into
place, so a crash, a full disk or Ctrl-C never leaves a half-written output.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import yaml

from hound_id.errors import OutputError, SpecError


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    Raises:
        OutputError: The folder does not exist or the file cannot be written.
    """
    target = Path(path)
    folder = _file_folder(target)
    tmp: Path | None = None
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=folder)
        os.close(fd)
        tmp = Path(tmp_name)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual permissions
        yield tmp
        os.replace(tmp, target)
    except OSError as err:
        raise _cannot_write(err, str(target)) from err
    finally:
        if tmp is not None and tmp.exists():
            tmp.unlink()


def _cannot_write(err: OSError, what: str) -> OutputError:
    """The one-line error for an OSError met while writing ``what`` (an OutputError is kept)."""
    if isinstance(err, OutputError):
        return err
    return OutputError(
        f"{what}: cannot write ({err.strerror or err}); check the folder's permissions and free space", path=what
    )


_SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,99}")


def file_stem(name: object, where: str) -> str:
    """``name`` if it can safely become part of a file name, else a one-line :class:`SpecError`.

    Names taken from input files (a robot's or a motor's ``name:``) become output file names;
    a name holding a path separator, ``..`` or a leading dot could write outside the output
    folder or hide the file, so only letters, digits and ``_ . + -`` are accepted.

    Args:
        name: The name as read from the file.
        where: "file: field 'name'", for the message.
    """
    if not isinstance(name, str) or not name:
        raise SpecError(f"{where}: found {name!r}, expected a name in text (for example hound-like)")
    if not _SAFE_NAME.fullmatch(name) or ".." in name:
        raise SpecError(
            f"{where}: found {name!r}; the name becomes part of output file names, so use only letters, digits "
            "and _ . + - (no path separators, no '..', at most 100 characters, starting with a letter or digit)"
        )
    return name


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_output(
    path: str | os.PathLike[str] | None,
    suffixes: tuple[str, ...],
    what: str,
    inputs: Sequence[str | os.PathLike[str] | None] = (),
) -> None:
    """Fail before any work if an output cannot be written: missing folder, wrong file type, or an input.

    Args:
        path: The output path (None: nothing to check).
        suffixes: Accepted suffixes, lower case with the dot (".png").
        what: What the file is, for the message.
        inputs: The command's input files: writing the output onto one of them would destroy it.
    """
    if path is None:
        return
    target = Path(path)
    for source in inputs:
        if source is not None and target.exists() and Path(source).exists() and os.path.samefile(target, source):
            raise OutputError(
                f"{target}: is also an input of this command ({source}); writing it would destroy the input: "
                "choose another output path",
                path=str(target),
            )
    if target.suffix.lower() not in suffixes:
        raise OutputError(
            f"{target}: {what} files end in {' or '.join(suffixes)}; found '{target.suffix or '(no suffix)'}'",
            path=str(target),
        )
    _file_folder(target)


def _file_folder(target: Path) -> Path:
    """The folder an output file goes into, once it is known to exist and be writable, and ``target`` no folder."""
    if target.is_dir():  # then its folder exists: the order of the checks does not matter
        raise OutputError(f"{target}: is a folder; give a file name", path=str(target))
    folder = target.parent if str(target.parent) else Path(".")
    _require_writable(folder, str(target), "output path", str(target))
    return folder


def _require_writable(folder: Path, who: str, instead: str, path: str) -> None:
    """Raise unless ``folder`` exists and can be written; ``who`` opens the message, ``instead`` ends it.

    ``path``: the output the error is about (its ``path`` attribute).
    """
    if not folder.is_dir():
        raise OutputError(f"{who}: folder {folder} does not exist; create it or choose another {instead}", path=path)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(
            f"{who}: folder {folder} is not writable; choose another {instead} or change its permissions", path=path
        )


def check_folder(path: str | os.PathLike[str] | None, option: str = "--out") -> None:
    """Fail before any work if an output folder cannot be made or written (None: nothing to check)."""
    if path is None:
        return
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{option} {folder}: is a file; give a folder", path=str(folder))
    probe = folder if folder.is_dir() else folder.resolve().parent
    _require_writable(probe, f"{option} {folder}", option, str(folder))


def make_folder(path: str | os.PathLike[str], option: str = "--out") -> Path:
    """Create the output folder ``path`` (its parent must exist) and check it can be written.

    Raises:
        OutputError: ``path`` is a file, its parent is missing, or it cannot be created or written.
    """
    folder = Path(path)
    check_folder(folder, option)
    try:
        folder.mkdir(exist_ok=True)
    except OSError as err:
        raise OutputError(
            f"{option} {folder}: cannot create the folder ({err.strerror or err}); choose another {option}",
            path=str(folder),
        ) from err
    return folder  # writable: check_folder saw it, or its parent, writable


@contextmanager
def staged_folder(path: str | os.PathLike[str], option: str = "--out") -> Iterator[Path]:
    """Yield a temporary folder beside ``path``; on success move its files into ``path`` (created).

    The files of one command appear together or not at all: a failure while writing (or
    Ctrl-C) leaves ``path`` as it was. The staging folder sits at the same depth as ``path``,
    so relative paths computed from ``path`` hold for files written into it.

    Raises:
        OutputError: ``path`` is a file, its parent is missing, or it cannot be created or written.
    """
    folder = Path(path)
    parent = folder.resolve().parent  # "." and "out/.." have a parent too
    check_folder(folder, option)
    staging: Path | None = None
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=parent))
        yield staging
        make_folder(folder, option)
        for item in sorted(staging.iterdir()):
            os.replace(item, folder / item.name)
    except OSError as err:
        raise _cannot_write(err, f"{option} {folder}") from err
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_with(path: str | os.PathLike[str], writer: Callable[[IO[bytes]], Any]) -> None:
    """Call ``writer`` with a binary file object and move the result onto ``path`` atomically."""
    with atomic_path(path) as tmp, tmp.open("wb") as handle:
        writer(handle)


def write_png(fig: Any, path: str | os.PathLike[str], dpi: int = 120) -> None:
    """Save a matplotlib figure as PNG atomically, at ``dpi`` dots per inch (the folder must exist)."""
    write_with(path, lambda handle: fig.savefig(handle, format="png", dpi=dpi))


def write_json(path: str | os.PathLike[str], data: Any) -> None:
    """Write ``data`` as indented JSON atomically."""
    write_text(path, json.dumps(data, indent=2) + "\n")


class DuplicateKeyError(yaml.YAMLError):
    """A mapping repeats a key (PyYAML would silently keep the last value)."""

    def __init__(self, key: object, line: int) -> None:
        super().__init__(f"duplicate key {key!r}")
        self.key, self.line = key, line


class _UniqueKeyLoader(yaml.SafeLoader):
    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[object, object]:
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)  # type: ignore[no-untyped-call]
            if key in seen:
                raise DuplicateKeyError(key, key_node.start_mark.line + 1)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def read_yaml(path: str | os.PathLike[str], what: str) -> Any:
    """Read a YAML file, turning I/O and syntax problems into one-line :class:`SpecError`.

    Args:
        path: File to read.
        what: What the file should be ("motor spec", "robot"), for messages.
    """
    source = Path(path)
    if source.is_dir():
        raise SpecError(f"{source}: is a folder; expected a {what} YAML file", path=str(source))
    try:
        text = source.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise SpecError(f"{source}: file not found; expected a {what} YAML file", path=str(source)) from err
    except (OSError, UnicodeDecodeError) as err:
        raise SpecError(f"{source}: cannot read the {what} file ({err})", path=str(source)) from err
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except DuplicateKeyError as err:
        raise SpecError(
            f"{source}: line {err.line}: key '{err.key}' appears twice; keep one", path=str(source)
        ) from err
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise SpecError(
            f"{source}:{line} is not valid YAML ({problem}); fix the syntax of the {what} file",
            path=str(source),
        ) from err
