"""Atomic output: every file hound-id writes appears whole or not at all.

Writers produce a temporary file beside the target and ``os.replace`` it into
place, so a crash, a full disk or Ctrl-C never leaves a half-written output.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import yaml

from hound_id.errors import HoundIdError, OutputError, SpecError

#: The largest YAML file read (a motor spec, a robot, a rig, a plan, a bundle) [bytes]: the biggest one a user
#: writes is a few kB; megabytes are a wrong path, not a spec.
YAML_MAX_BYTES = 1 << 20
#: The most values a YAML document may expand to through its aliases, and its deepest nesting: a spec's own
#: structure is a few hundred values four levels deep; nine levels of nine aliases would be 387 million.
YAML_MAX_VALUES = 100_000
YAML_MAX_DEPTH = 64
#: The largest URDF, foot.json or effects file read [bytes]: a leg's URDF is tens of kB (meshes are separate files).
TEXT_MAX_BYTES = 16 << 20


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
        os.chmod(tmp, 0o666 & ~umask())  # mkstemp makes 0600; outputs get the usual permissions
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


def umask() -> int:
    """The process's umask (read without changing it)."""
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
    kind = special_kind(target)
    if kind is not None:
        raise OutputError(
            f"{target}: is {kind}, not a regular file; outputs are written beside it and renamed onto it: "
            "give the path of a file",
            path=str(target),
        )
    source = _input_at(target, inputs)
    if source is not None:
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


_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def special_kind(path: str | os.PathLike[str]) -> str | None:
    """What ``path`` is when it exists and is neither a regular file nor a folder ("a FIFO (named pipe)", "a
    character device", ...; symlinks followed), else None. Such a file is never opened: a FIFO blocks until a
    writer comes, a device such as /dev/zero never ends."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def check_input(
    path: str | os.PathLike[str],
    what: str,
    error: type[HoundIdError] = SpecError,
    max_bytes: int | None = None,
    option: str | None = None,
) -> int:
    """Fail in one line unless ``path`` is a regular file of at most ``max_bytes``; return its size [bytes].

    Args:
        path: The input file.
        what: What it should be ("motor spec YAML", "URDF"), for the message.
        error: The error type raised (the caller's family member).
        max_bytes: The largest size accepted (None: any).
        option: The option that named the file ("--urdf"), said before its path.
    """
    source = Path(path)
    name = f"{option} {source}" if option else str(source)
    try:
        info = os.stat(source)
    except FileNotFoundError as err:
        raise error(f"{name}: file not found; expected a {what} file", path=str(source)) from err
    except (OSError, ValueError) as err:
        raise error(f"{name}: cannot read it ({getattr(err, 'strerror', None) or err})", path=str(source)) from err
    if stat.S_ISDIR(info.st_mode):
        raise error(f"{name}: is a folder; expected a {what} file", path=str(source))
    kind = special_kind(source)
    if kind is not None:
        raise error(
            f"{name}: is {kind}, not a regular file; expected a {what} file (a pipe or device is never read: "
            "save what it gives to a file first)",
            path=str(source),
        )
    if max_bytes is not None and info.st_size > max_bytes:
        raise error(
            f"{name}: is {info.st_size / 1e6:.3g} MB; a {what} file is at most {max_bytes / 1e6:.3g} MB: "
            "is this the right file?",
            path=str(source),
        )
    return info.st_size


def read_bounded_text(
    path: str | os.PathLike[str],
    what: str,
    max_bytes: int,
    error: type[HoundIdError] = SpecError,
    option: str | None = None,
) -> str:
    """The text (UTF-8) of a regular file of at most ``max_bytes``, else a one-line error of type ``error``.

    The bound holds while reading too: a file that grows, or reports no size (as /proc files do), is cut off."""
    source = Path(path)
    check_input(source, what, error, max_bytes, option)
    try:
        with open(source, "rb") as handle:
            data = handle.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise error(
                f"{source}: holds more than {max_bytes / 1e6:.3g} MB; a {what} file is at most that: is this the "
                "right file?",
                path=str(source),
            )
        return data.decode("utf-8")
    except FileNotFoundError as err:
        raise error(f"{source}: file not found; expected a {what} file", path=str(source)) from err
    except UnicodeDecodeError as err:
        raise error(
            f"{source}: is not UTF-8 text (byte {err.object[err.start]:#04x} at {err.start}); save it as UTF-8 "
            f"(iconv -t UTF-8 {source.name} > utf8-{source.name}) and read the copy",
            path=str(source),
        ) from err
    except OSError as err:
        raise error(f"{source}: cannot read the {what} file ({err})", path=str(source)) from err


def read_json(
    path: str | os.PathLike[str],
    what: str,
    max_bytes: int,
    error: type[HoundIdError] = SpecError,
    option: str | None = None,
) -> Any:
    """A JSON file's content: a regular file of at most ``max_bytes``, UTF-8, strict JSON (no NaN or Infinity,
    nesting Python can hold, integers it can read), else a one-line error of type ``error``."""
    source = Path(path)
    name = f"{option} {source}" if option else str(source)
    text = read_bounded_text(source, what, max_bytes, error, option)

    def constant(word: str) -> Any:
        raise ValueError(f"{word} is not a JSON number")

    try:
        return json.loads(text, parse_constant=constant)
    except json.JSONDecodeError as err:
        raise error(f"{name}: not JSON ({err.msg}, line {err.lineno}); give the {what}", path=str(source)) from err
    except (ValueError, RecursionError) as err:
        first = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise error(f"{name}: not JSON hound-id reads ({first}); give the {what}", path=str(source)) from err


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
        kind = special_kind(folder) or "a file"
        raise OutputError(f"{option} {folder}: is {kind}; give a folder", path=str(folder))
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
def staged_folder(
    path: str | os.PathLike[str],
    option: str = "--out",
    inputs: Sequence[str | os.PathLike[str] | None] = (),
) -> Iterator[Path]:
    """Yield a temporary folder beside ``path``; on success move its files into ``path`` (created).

    The files of one command appear together or not at all: a failure while writing (or
    Ctrl-C) leaves ``path`` as it was. The staging folder sits at the same depth as ``path``,
    so relative paths computed from ``path`` hold for files written into it. Files in
    subfolders of the staging folder go to the same subfolders of ``path`` (created); each
    replaces the file of its name there, and the other files of ``path`` are kept. A staged
    file that would land on a folder, or a subfolder on a file, or onto one of the command's
    ``inputs`` (a robot file or URDF kept in the output folder), fails before the first move.

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
        moves = [(item, folder / item.relative_to(staging)) for item in sorted(staging.rglob("*")) if not item.is_dir()]
        for _, target in moves:  # every clash before the first move: a clash leaves ``path`` as it was
            _check_clash(folder, target, option)
            _check_not_input(target, inputs, option)
        for item, target in moves:
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(item, target)
    except OSError as err:
        raise _cannot_write(err, f"{option} {folder}") from err
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)


def _check_not_input(target: Path, inputs: Sequence[str | os.PathLike[str] | None], option: str) -> None:
    """Raise when writing ``target`` would replace one of ``inputs``."""
    source = _input_at(target, inputs)
    if source is not None:
        raise OutputError(
            f"{option} {target.parent}: writing {target.name} there would replace the input {source}; choose "
            f"another {option} (or move the input out of it)",
            path=str(target),
        )


def _input_at(target: Path, inputs: Sequence[str | os.PathLike[str] | None]) -> str | os.PathLike[str] | None:
    """The input that ``target`` is (the same file, through any link or path), else None."""
    if not target.exists():
        return None
    return next((s for s in inputs if s is not None and Path(s).exists() and os.path.samefile(target, s)), None)


def _check_clash(folder: Path, target: Path, option: str) -> None:
    """Raise when the staged file ``target`` (in ``folder``) would land on a folder, or its folder on a file."""
    if target.is_dir():
        raise OutputError(
            f"{option} {folder}: {target} is a folder where a file goes; move it away or choose another {option}",
            path=str(folder),
        )
    for parent in target.relative_to(folder).parents:
        if (folder / parent).exists() and not (folder / parent).is_dir():
            raise OutputError(
                f"{option} {folder}: {folder / parent} is a file where a folder goes; move it away or choose another "
                f"{option}",
                path=str(folder),
            )


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


def json_text(data: Any) -> str:
    """``data`` as the indented JSON every hound-id file holds."""
    return json.dumps(data, indent=2) + "\n"


def write_json(path: str | os.PathLike[str], data: Any) -> None:
    """Write ``data`` as indented JSON atomically."""
    write_text(path, json_text(data))


class DuplicateKeyError(yaml.YAMLError):
    """A mapping repeats a key (PyYAML would silently keep the last value)."""

    def __init__(self, key: object, line: int) -> None:
        super().__init__(f"duplicate key {key!r}")
        self.key, self.line = key, line


class YamlShapeError(yaml.YAMLError):
    """A document hound-id does not read: a key that is not a plain value, nesting or alias expansion past the
    bounds, an alias inside itself."""

    def __init__(self, problem: str, line: int) -> None:
        super().__init__(problem)
        self.problem, self.line = problem, line


class _UniqueKeyLoader(yaml.SafeLoader):
    """Safe YAML, with plain keys only, each once, nesting at most :data:`YAML_MAX_DEPTH` deep and at most
    :data:`YAML_MAX_VALUES` values once the aliases are expanded (checked before anything is built)."""

    _depth = 0

    def compose_node(self, parent: yaml.Node | None, index: object) -> yaml.Node:
        self._depth += 1
        try:
            if self._depth > YAML_MAX_DEPTH:
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]
                raise YamlShapeError(f"nested more than {YAML_MAX_DEPTH} levels deep", mark.line + 1)
            return super().compose_node(parent, index)  # type: ignore[no-untyped-call,no-any-return]
        finally:
            self._depth -= 1

    def get_single_node(self) -> yaml.Node | None:
        node = super().get_single_node()  # type: ignore[no-untyped-call]
        if node is not None:
            count = _expanded(node, {}, set())
            if count > YAML_MAX_VALUES:
                raise YamlShapeError(
                    f"it holds {count:,} values (its aliases *name expanded); at most {YAML_MAX_VALUES:,} are read: "
                    "is this the right file? (write repeated parts once, without aliases)",
                    node.start_mark.line + 1,
                )
        return node  # type: ignore[no-any-return]

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[object, object]:
        seen = set()
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                raise YamlShapeError(
                    "a key that is a list or mapping ('? [a, b]' or '[a, b]: ...'); keys are plain names",
                    key_node.start_mark.line + 1,
                )
            if key_node.tag == "tag:yaml.org,2002:merge":  # '<<: *base': its keys may be overridden here
                continue
            key = self.construct_object(key_node, deep=deep)  # type: ignore[no-untyped-call]
            if key in seen:
                raise DuplicateKeyError(key, key_node.start_mark.line + 1)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def _expanded(node: yaml.Node, sizes: dict[int, int], open_nodes: set[int]) -> int:
    """How many values ``node`` holds once its aliases are expanded (each shared node counted once per use);
    linear in the distinct nodes (their counts are kept in ``sizes``)."""
    key = id(node)
    if key in sizes:
        return sizes[key]
    if key in open_nodes:
        raise YamlShapeError(
            "an alias inside the value it names (*name within &name): it never ends", node.start_mark.line + 1
        )
    open_nodes.add(key)
    if isinstance(node, yaml.SequenceNode):
        count = 1 + sum(_expanded(item, sizes, open_nodes) for item in node.value)
    elif isinstance(node, yaml.MappingNode):
        count = 1 + sum(_expanded(k, sizes, open_nodes) + _expanded(v, sizes, open_nodes) for k, v in node.value)
    else:
        count = 1
    open_nodes.discard(key)
    sizes[key] = count
    return count


def read_yaml(path: str | os.PathLike[str], what: str) -> Any:
    """Read a YAML file, turning I/O and syntax problems into one-line :class:`SpecError`.

    The file must be a regular file of at most :data:`YAML_MAX_BYTES`; its keys plain values, each once; its
    nesting and alias expansion bounded (:class:`_UniqueKeyLoader`).

    Args:
        path: File to read.
        what: What the file should be ("motor spec", "robot"), for messages.
    """
    source = Path(path)
    text = read_bounded_text(source, f"{what} YAML", YAML_MAX_BYTES)
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except DuplicateKeyError as err:
        raise SpecError(
            f"{source}: line {err.line}: key '{err.key}' appears twice; keep one", path=str(source)
        ) from err
    except (ValueError, OverflowError) as err:  # a value YAML's own types cannot hold (an int of 5,000 digits)
        first = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise SpecError(f"{source}: a value cannot be read ({first}); fix the {what} file", path=str(source)) from err
    except YamlShapeError as err:
        raise SpecError(
            f"{source}: line {err.line}: {err.problem}; the {what} file cannot be read", path=str(source)
        ) from err
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise SpecError(
            f"{source}:{line} is not valid YAML ({problem}); fix the syntax of the {what} file",
            path=str(source),
        ) from err
