"""The output directory: a run writes only plain files directly inside it, lists every file
it writes in the directory's manifest, and never replaces earlier results unless asked.

The manifest (:data:`MANIFEST`, one file name a line) is appended to just before each file
is created, so it lists every file of the run even when the run is killed. ``--overwrite``
removes exactly the files the previous manifest lists that are plain files directly inside
the directory (for output written before manifests existed: the files the previous ``.pvd``
lists, the ``.pvd`` itself and the fixed files of a run). A symbolic link is never followed
and never removed; a name the run writes that is a link, a directory or a file with other
hard links stops the run before anything is written (the run would write through it).
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
import stat
from pathlib import Path

from ..errors import FemFracError

#: The manifest of the run that wrote the directory (hidden: it is no result).
MANIFEST = ".fem_frac_manifest"
_HEADER = "# fem_frac manifest: the files the run wrote here (--overwrite removes these)\n"

#: Files every run writes under fixed names (the driver writes them; status through a
#: temporary file and a rename).
FIXED = ("summary.json", "summary.json.tmp", "history.csv", "case.resolved.yaml")

# Output written before manifests existed: these names make a directory occupied.
OWNED = (
    "{name}.pvd", "{name}.pvd.tmp", "{name}_*.vtu", "summary.json", "case.resolved.yaml",
    "history.csv",
)

#: Longest file name a run takes (bytes, UTF-8); the series add up to 17 characters.
NAME_MAX_BYTES = 128


def name_problem(name: str) -> str | None:
    """Why ``name`` is no plain file name (``None`` when it is one): empty, ``.``/``..``, a
    path separator, a NUL or other control character, or longer than
    :data:`NAME_MAX_BYTES`."""
    if not name:
        return "is empty"
    if name in (".", ".."):
        return f"{name!r} is a directory, not a file name"
    if "/" in name or "\\" in name:
        return "must be a plain file name, without '/' or '\\' (the output directory is -o "\
               "DIR or output.directory)"
    if re.search(r"[\x00-\x1f\x7f]", name):
        return "must not contain control characters (NUL, newline, ...)"
    if len(name.encode("utf-8", "surrogatepass")) > NAME_MAX_BYTES:
        return f"is longer than {NAME_MAX_BYTES} bytes"
    return None


def _plain(name: str) -> str:
    problem = name_problem(name)
    if problem is not None:
        raise FemFracError(f"output name {name!r}: {problem}")
    return name


class Manifest:
    """The list of files a run writes in ``directory``: :meth:`add` each name before the
    file is created (it returns the path to write). Instances on the same directory append
    to the same file; a name is listed once per instance."""

    def __init__(self, directory: Path | str):
        self.directory = Path(directory)
        self._added: set[str] = set()

    @property
    def path(self) -> Path:
        return self.directory / MANIFEST

    def add(self, *names: str) -> Path:
        """Record ``names`` (plain file names) as written by the run; returns the path of the
        last one. Raises :class:`FemFracError` when one exists as something the run must not
        write through (a symbolic link, a directory, a file with other hard links)."""
        path = self.directory
        new = []
        for name in names:
            path = self.directory / _plain(name)
            problem = _not_writable(path)
            if problem is not None:
                raise FemFracError(problem)
            if name not in self._added:
                new.append(name)
        if new:
            self._append("".join(f"{n}\n" for n in new))
            self._added.update(new)
        return path

    def names(self) -> list[str]:
        """The names listed (those of earlier runs included until :meth:`start`)."""
        return listed(self.directory)

    def start(self) -> None:
        """Begin an empty list (the directory holds no file of a run any more)."""
        fd = _open_plain(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        with os.fdopen(fd, "w") as f:
            f.write(_HEADER)
        self._added.clear()

    def _append(self, text: str) -> None:
        exists = os.path.lexists(self.path)
        fd = _open_plain(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
        try:
            os.write(fd, ((_HEADER if not exists else "") + text).encode())
        finally:
            os.close(fd)


def listed(directory: Path) -> list[str]:
    """The file names the manifest of ``directory`` lists (empty without one); an
    unfinished last line (a run killed while appending) is left out."""
    path = Path(directory) / MANIFEST
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return []
        text = path.read_text(errors="surrogateescape")
    except OSError:
        return []
    lines = text.split("\n")[:-1]  # the part after the last newline is unfinished
    return [ln for ln in lines if ln and not ln.startswith("# fem_frac manifest")]


def check_directory(directory: Path, name: str, overwrite: bool) -> None:
    """Raise the :class:`FemFracError` :func:`prepare_directory` would raise, creating and
    removing nothing: ``directory`` cannot be made, or holds results of an earlier run and
    ``overwrite`` is false, or a name the run writes is something it must not write
    through."""
    _check(Path(directory), name, overwrite)


def prepare_directory(directory: Path, name: str, overwrite: bool) -> Path:
    """Create ``directory`` for a run named ``name`` and start its manifest.

    Refuses (:class:`FemFracError`) when it holds results of an earlier run unless
    ``overwrite``; then removes exactly the files of the earlier run (see the module's
    docstring), nothing else.
    """
    directory = Path(directory)
    remove = _check(directory, name, overwrite)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FemFracError(f"{directory}: cannot create the output directory: "
                           f"{exc.strerror or exc}") from None
    for n in remove:
        _remove_plain(directory, n)
    try:
        Manifest(directory).start()
    except OSError as exc:
        raise FemFracError(f"{directory}: cannot write in the output directory: "
                           f"{exc.strerror or exc}") from None
    return directory


# --- helpers ---------------------------------------------------------------------------------


def _check(directory: Path, name: str, overwrite: bool) -> list[str]:
    """The checks of :func:`check_directory`; returns the names ``--overwrite`` removes."""
    _plain(name)
    check_location(directory)
    if not os.path.isdir(directory):
        return []
    earlier = _earlier_files(directory, name)
    if earlier and not overwrite:
        raise FemFracError(
            f"{directory}: holds results of an earlier run ({earlier[0]}); "
            "pass --overwrite to replace them or -o DIR to write elsewhere"
        )
    remove = _removed_by_overwrite(directory, name) if overwrite else []
    gone = set(remove)
    for n in _written_names(directory, name):
        if n in gone and _is_plain_file(directory / n):
            continue  # removed before the run writes it
        problem = _not_writable(directory / n)
        if problem is not None:
            raise FemFracError(problem)
    return remove


def check_location(directory: Path) -> None:
    """Raise :class:`FemFracError` unless ``directory`` is a writable directory or its
    nearest existing parent is one (it can be made); creates nothing."""
    directory = Path(directory)
    if "\0" in str(directory):
        raise FemFracError(f"{str(directory)!r}: a path cannot contain a NUL character")
    if os.path.lexists(directory) and not os.path.isdir(directory):
        raise FemFracError(f"{directory}: exists and is not a directory")
    for parent in [directory, *directory.parents]:
        if os.path.isdir(parent):
            if not os.access(parent, os.W_OK | os.X_OK):
                what = "the output directory" if parent == directory else f"{parent}"
                raise FemFracError(f"{directory}: cannot write in {what} (permission denied)")
            return
        if os.path.lexists(parent):
            raise FemFracError(f"{directory}: cannot create the output directory: {parent} "
                               "is not a directory")
    raise FemFracError(f"{directory}: cannot create the output directory")


def _is_plain_file(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _not_writable(path: Path) -> str | None:
    """Why the run must not write ``path`` (``None``: absent or a plain file of its own)."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"{path}: cannot write it: {exc.strerror or exc}"
    if stat.S_ISLNK(st.st_mode):
        return (f"{path}: is a symbolic link; a run writes only plain files inside its "
                "directory and never through a link: remove it or write elsewhere (-o DIR)")
    if not stat.S_ISREG(st.st_mode):
        return (f"{path}: exists and is not a plain file; the run writes a file of that name: "
                "remove it or write elsewhere (-o DIR)")
    if st.st_nlink > 1:
        return (f"{path}: has other hard links; writing it would change them too: remove it "
                "or write elsewhere (-o DIR)")
    return None


def _names_matching(directory: Path, pattern: str) -> list[str]:
    return sorted(os.path.basename(p) for p in glob.glob(os.path.join(
        glob.escape(str(directory)), pattern)))


def _earlier_files(directory: Path, name: str) -> list[str]:
    """Files of an earlier run: those its manifest lists, and any of the names runs wrote
    before manifests existed."""
    found = [n for n in listed(directory) if name_problem(n) is None
             and _is_plain_file(directory / n)]
    legacy = [n for pattern in OWNED
              for n in _names_matching(directory, pattern.format(name=glob.escape(name)))]
    return list(dict.fromkeys(found + [n for n in legacy if _is_plain_file(directory / n)]))


def _removed_by_overwrite(directory: Path, name: str) -> list[str]:
    """What ``--overwrite`` removes: the manifest's files; without a manifest, the files
    the ``.pvd`` of ``name`` (and of its crack series) list, those ``.pvd`` and the fixed
    files of a run."""
    if os.path.lexists(directory / MANIFEST):
        names = listed(directory)
    else:
        names = []
        for series in (name, f"{name}_crack"):
            names += [*_pvd_files(directory / f"{series}.pvd"), f"{series}.pvd",
                      f"{series}.pvd.tmp"]
        names += FIXED
    return list(dict.fromkeys(n for n in names if name_problem(n) is None))


_DATASET_FILE = re.compile(r"<DataSet\b[^>]*?\bfile\s*=\s*(\"[^\"]*\"|'[^']*')")


def _pvd_files(pvd: Path) -> list[str]:
    """The files a ``.pvd`` lists that are plain names (a file in the same directory)."""
    if not _is_plain_file(pvd):
        return []
    try:
        text = pvd.read_text(errors="replace")
    except OSError:
        return []
    from xml.sax.saxutils import unescape

    names = [unescape(m.group(1)[1:-1], {"&quot;": '"', "&apos;": "'"})
             for m in _DATASET_FILE.finditer(text)]
    return [n for n in names if name_problem(n) is None]


def _written_names(directory: Path, name: str) -> list[str]:
    """Names the run (or the driver) writes that exist now: fixed ones, the series'
    indices and scratch files, the frames; a link or directory at one of them stops the
    run."""
    fixed = [*FIXED, MANIFEST, f"{name}_view.py", f"{name}_probes.csv"]
    for series in (name, f"{name}_crack", f"{name}_obstacles"):
        fixed += [f"{series}.pvd", f"{series}.pvd.tmp", f"{series}.vtu.tmp",
                  f"{series}.vtkhdf"]
    frames = _names_matching(directory, f"{glob.escape(name)}_*.vtu")
    return [n for n in fixed if os.path.lexists(directory / n)] + frames


def _remove_plain(directory: Path, name: str) -> None:
    """Remove ``directory/name`` if it is a plain file (a link is not followed, nor
    removed)."""
    path = directory / name
    if _is_plain_file(path):
        try:
            os.unlink(path)
        except FileNotFoundError:
            pass
        except OSError as exc:
            raise FemFracError(f"{path}: cannot remove it: {exc.strerror or exc}") from None


def _open_plain(path: Path, flags: int) -> int:
    """``os.open`` that refuses to follow a symbolic link at ``path``."""
    try:
        return os.open(path, flags | getattr(os, "O_NOFOLLOW", 0), 0o666)
    except OSError as exc:
        problem = _not_writable(path)
        raise FemFracError(problem or f"{path}: cannot write it: {exc.strerror or exc}") \
            from None


def create_plain(path: Path) -> None:
    """Create (or empty) the plain file ``path``, never through a symbolic link."""
    os.close(_open_plain(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC))


def replace_file(path: Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` through a new scratch file beside it and a rename: a
    symbolic link at ``path`` is replaced, never written through, and a reader never sees
    half a file."""
    import secrets

    path = Path(path)
    while True:  # a new name (O_EXCL: nothing there is followed), permissions from the umask
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            break
        except FileExistsError:
            continue
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
