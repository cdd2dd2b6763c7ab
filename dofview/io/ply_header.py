"""PLY headers: the format, the elements with their properties and counts, and the comments.

Shared by the Inria 3DGS reader (ply.py) and the PlayCanvas compressed reader (compressed_ply.py),
which both check a header against the file size before reading a body.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dofview.errors import DofviewError
from dofview.io._common import input_size

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
MAX_HEADER = 1 << 20


class Element:
    def __init__(self, name: str, count: int) -> None:
        self.name, self.count = name, count
        self.props: list[tuple[str, str | None]] = []  # (name, numpy type or None for a list)
        self.min_binary_row = 0  # bytes: scalars plus list counts (lists may be empty)

    def min_body_bytes(self, fmt: str) -> int:
        """The fewest body bytes ``count`` rows can take: an ASCII value needs a digit and a separator."""
        return self.count * max(2 * len(self.props) if fmt == "ascii" else self.min_binary_row, 1)


def parse_header(path: Path, head: bytes) -> tuple[str, list[Element], list[str], int]:
    """(format, elements, comments, header length in bytes) from the start of a file."""
    if not head.startswith(b"ply"):
        raise DofviewError(f"{path}: not a PLY file (it does not start with 'ply')")
    end = head.find(b"end_header")
    if end < 0:
        raise DofviewError(f"{path}: PLY header has no 'end_header' line (file cut short or not a PLY)")
    nl = head.find(b"\n", end)
    if nl < 0:
        raise DofviewError(f"{path}: PLY header has no line break after 'end_header' (file cut short)")
    try:
        text = head[:end].decode("ascii")
    except UnicodeDecodeError:
        raise DofviewError(f"{path}: PLY header holds non-ASCII bytes") from None
    fmt, elements, comments = None, [], []
    for lineno, line in enumerate(text.replace("\r", "").split("\n")[1:], start=2):
        words = line.split()
        if not words:
            continue
        kw = words[0]
        if kw == "format":
            if len(words) < 2 or words[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise DofviewError(f"{path}: unknown PLY format in header line {lineno}: {line.strip()!r}")
            fmt = words[1]
        elif kw in ("comment", "obj_info"):
            comments.append(line.split(None, 1)[1].strip() if len(words) > 1 else "")
        elif kw == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise DofviewError(f"{path}: bad element line {lineno} in PLY header: {line.strip()!r}")
            elements.append(Element(words[1], int(words[2])))
        elif kw == "property":
            if not elements:
                raise DofviewError(f"{path}: property before any element in PLY header line {lineno}")
            if words[-1] in (name for name, _ in elements[-1].props):
                raise DofviewError(f"{path}: property {words[-1]!r} appears twice in PLY header line {lineno}")
            if len(words) == 3 and words[1] in PLY_TYPES:
                elements[-1].props.append((words[2], PLY_TYPES[words[1]]))
                elements[-1].min_binary_row += np.dtype(PLY_TYPES[words[1]]).itemsize
            elif len(words) == 5 and words[1] == "list" and words[2] in PLY_TYPES and words[3] in PLY_TYPES:
                elements[-1].props.append((words[4], None))
                elements[-1].min_binary_row += np.dtype(PLY_TYPES[words[2]]).itemsize
            else:
                raise DofviewError(f"{path}: bad property line {lineno} in PLY header: {line.strip()!r}")
        else:
            raise DofviewError(f"{path}: unexpected PLY header line {lineno}: {line.strip()!r}")
    if fmt is None:
        raise DofviewError(f"{path}: PLY header has no 'format' line")
    return fmt, elements, comments, nl + 1


def read_header(path: Path) -> tuple[int, str, list[Element], list[str], int]:
    """(file size, format, elements, comments, header length in bytes) of a PLY file.

    Raises:
        DofviewError: the file is missing, unreadable, or its header is not a PLY header.
    """
    size = input_size(path)
    try:
        with open(path, "rb") as f:
            head = f.read(MAX_HEADER)
    except OSError as e:
        raise DofviewError(f"{path}: cannot read ({e.strerror or e})") from None
    return (size, *parse_header(path, head))
