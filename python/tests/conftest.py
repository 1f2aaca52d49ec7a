"""Fixtures of the scanatlas Python tests: a small fragmented scan written by hand (OBJ, MTL and
a PNG made with zlib), so the tests need nothing but the package itself."""

import struct
import zlib
from pathlib import Path

import pytest


def write_png(path: Path, width: int, height: int) -> None:
    """An RGB PNG with a smooth colour ramp (every texel different enough to see a resampling)."""
    rows = bytearray()
    for y in range(height):
        rows.append(0)
        for x in range(width):
            rows += bytes(((x * 255) // width, (y * 255) // height, ((x + y) * 7) % 256))

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(bytes(rows)))
        + chunk(b"IEND", b"")
    )


def write_grid_scan(folder: Path, n: int = 6, texture_side: int = 128) -> Path:
    """A gently curved n×n grid whose every quad is its own UV chart, as raw photogrammetry
    atlases are: the defragmentation has many seams to merge."""
    lines = ["mtllib scan.mtl"]
    for j in range(n + 1):
        for i in range(n + 1):
            z = 0.05 * ((i - n / 2) ** 2 + (j - n / 2) ** 2) / n
            lines.append(f"v {i / n:.6f} {j / n:.6f} {z:.6f}")
    cell = 1.0 / n
    for j in range(n):
        for i in range(n):
            # Each chart sits in its own cell of the texture, with a margin.
            u0, v0 = i * cell + 0.1 * cell, j * cell + 0.1 * cell
            s = 0.8 * cell
            lines += [f"vt {u0:.6f} {v0:.6f}", f"vt {u0 + s:.6f} {v0:.6f}",
                      f"vt {u0 + s:.6f} {v0 + s:.6f}", f"vt {u0:.6f} {v0 + s:.6f}"]
    lines.append("usemtl skin")
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i + 1
            b, c, d = a + 1, a + n + 2, a + n + 1
            t = 4 * (j * n + i) + 1
            lines.append(f"f {a}/{t} {b}/{t + 1} {c}/{t + 2}")
            lines.append(f"f {a}/{t} {c}/{t + 2} {d}/{t + 3}")
    (folder / "scan.obj").write_text("\n".join(lines) + "\n")
    (folder / "scan.mtl").write_text("newmtl skin\nmap_Kd scan.png\n")
    write_png(folder / "scan.png", texture_side, texture_side)
    return folder / "scan.obj"


@pytest.fixture
def scan(tmp_path: Path) -> Path:
    return write_grid_scan(tmp_path)
