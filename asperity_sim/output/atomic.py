"""Files written whole and atomically: the one way the package writes a file.

Every file (run files, checkpoints, figures, CSV tables, scene files) is written to a
temporary ``.<name>.<pid>.<random>.tmp`` in the target folder, flushed to disk, then renamed
over the target, and the folder is synced: a crash or a kill leaves either the old file or the
new one under the final name, never a truncated one.  A failed write removes its temporary;
the next write of the same file removes those of killed processes
(:func:`remove_stale_temporaries`).  The temporary gets the usual permissions (0666 less the
umask), as a file opened for writing would.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

__all__ = ["write_atomically", "remove_stale_temporaries"]


def write_atomically(path, write) -> Path:
    """Write the file ``path`` by calling ``write(tmp)`` on a temporary path beside it, then renaming it.

    ``write`` must create the whole file at the path it is given (a ``str``; give a writer the
    format explicitly when it guesses it from the file name).  Its folder is created if needed.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600
    try:
        write(tmp)
        _fsync(tmp)
        os.replace(tmp, path)
        _fsync(path.parent)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def remove_stale_temporaries(path) -> list[Path]:
    """Remove ``.<name>.<pid>.<random>.tmp`` siblings of ``path`` whose writer is gone; return them.

    A temporary of a process that still runs (another writer of the same file) is left alone;
    one of this process can only be left over from an interrupted write.
    """
    path = Path(path)
    pattern = re.compile(re.escape(f".{path.name}.") + r"(\d+)\.[^/]*\.tmp")
    removed = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return removed
    for p in siblings:
        m = pattern.fullmatch(p.name)
        if m is None:
            continue
        pid = int(m.group(1))
        if pid != os.getpid() and _alive(pid):
            continue
        try:
            p.unlink()
            removed.append(p)
        except OSError:
            pass
    return removed


def _alive(pid) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # another user's process, or an absurd pid: keep the file
    return True


def _fsync(path):
    """Flush a file's or a folder's content to disk (best effort where the system does not allow it)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
