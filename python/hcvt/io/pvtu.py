"""PVTU (VTK XML parallel UnstructuredGrid): one index file over ``.vtu`` pieces.

The index names each piece's file (relative to the index) and declares the arrays every
piece holds: points as Float64 with 3 components (2D pieces lie in z = 0, as
:func:`hcvt.io.vtu.write_vtu` writes them), and the cell data by name and VTK type.
It holds no cells itself, so the client writes it without reading the pieces (VTK's file
format document, "Parallel File Formats").
"""

from __future__ import annotations

import os
from pathlib import Path
from xml.sax.saxutils import quoteattr


def write_pvtu(path: str | Path, pieces: list[str | Path], cell_data: dict[str, str]) -> Path:
    """Write the index ``path`` of the ``.vtu`` files ``pieces``.

    Parameters
    ----------
    path : str or Path
        The ``.pvtu`` file to write.
    pieces : list of str or Path
        The pieces' files, in order; written relative to ``path``'s directory.
    cell_data : dict of str to str
        Each cell array the pieces hold, by name, with its VTK type (``"Int64"``,
        ``"Float64"``, ...), in the pieces' order.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    here = path.parent.resolve()
    arrays = "".join(
        f"<PDataArray type={quoteattr(kind)} Name={quoteattr(name)}/>"
        for name, kind in cell_data.items()
    )
    scalars = f" Scalars={quoteattr(next(iter(cell_data)))}" if cell_data else ""
    sources = "".join(
        f"<Piece Source={quoteattr(Path(os.path.relpath(Path(p).resolve(), here)).as_posix())}/>"
        for p in pieces
    )
    path.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="PUnstructuredGrid" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64"><PUnstructuredGrid GhostLevel="0">'
        '<PPoints><PDataArray type="Float64" NumberOfComponents="3"/></PPoints>'
        f"<PCellData{scalars}>{arrays}</PCellData>{sources}"
        "</PUnstructuredGrid></VTKFile>\n"
    )
    return path
