"""Reading ``.npz`` archives that may be truncated, corrupt or not archives at all.

Each member is read whole by :mod:`zipfile`, which checks its CRC-32, before NumPy parses it,
so a flipped or missing byte is reported as such instead of reaching NumPy's header parser
(which raises assorted exceptions on garbled bytes: TokenError, TypeError, ValueError …).
Every failure is the caller's :class:`~chekhov.errors.ChekhovError` subclass naming the file.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from chekhov.errors import ChekhovError


def read_npz(path: Path, keys: Iterable[str] | None, error: type[ChekhovError],
             what: str) -> dict[str, np.ndarray]:
    """The arrays ``keys`` (None: all; absent ones are left out) of the ``.npz`` at ``path``.

    Args:
        error: the exception class to raise; what: the kind of file, e.g. ``"case"``.
    Raises:
        error: ``"{path}: no such {what} file"``, ``"{path}: not a chekhov {what} file, or
            truncated or corrupt (…)"`` or ``"{path}: {what} file is truncated or corrupt:
            array 'K' cannot be read (…)"``. Object (pickled) arrays are refused.
    """
    try:
        zf = zipfile.ZipFile(path)
    except FileNotFoundError as e:
        raise error(f"{path}: no such {what} file") from e
    except IsADirectoryError as e:
        raise error(f"{path}: is a folder, not a {what} file") from e
    except Exception as e:  # zipfile raises many types on a damaged central directory
        raise error(f"{path}: not a chekhov {what} file, or truncated or corrupt (cannot read "
                    f"it as .npz: {type(e).__name__}: {e})") from e
    data: dict[str, np.ndarray] = {}
    with zf:
        try:
            members = {n[:-4]: n for n in zf.namelist() if n.endswith(".npy")}
        except Exception as e:
            raise error(f"{path}: {what} file is corrupt: unreadable member names "
                        f"({type(e).__name__}: {e})") from e
        for k in members if keys is None else keys:
            if k not in members:
                continue
            try:
                raw = zf.read(members[k])  # checks the CRC-32
                data[k] = np.lib.format.read_array(io.BytesIO(raw), allow_pickle=False)
            except Exception as e:  # damaged member: zipfile, zlib or numpy's header parser
                raise error(f"{path}: {what} file is truncated or corrupt: array '{k}' cannot "
                            f"be read ({type(e).__name__}: {e})") from e
    return data
