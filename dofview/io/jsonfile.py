"""Reading a user's JSON file (cameras.json, a viewer script, …) with one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

from dofview.errors import DofviewError


def read_json(path: str | Path, what: str) -> object:
    """The parsed content of ``path``; ``what`` names the file in messages ("cameras file").

    Raises:
        DofviewError: the file cannot be read or is not valid JSON, naming the path.
    """
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except OSError as e:
        raise DofviewError(f"{path}: cannot read {what} ({e.strerror or e})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DofviewError(f"{path}: not a valid JSON {what} ({e})") from None
