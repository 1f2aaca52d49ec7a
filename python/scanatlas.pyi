"""Type stubs of the scanatlas extension module."""

from os import PathLike
from typing import Any, Callable, Optional, Union

__version__: str

_Path = Union[str, "PathLike[str]"]
_Progress = Optional[Callable[[str], Any]]

class ModelError(Exception):
    """A model (or one of its textures) is malformed or uses something scanatlas cannot handle."""

def defrag(
    input: _Path,
    output: _Path,
    *,
    progress: _Progress = None,
    **options: Any,
) -> dict[str, Any]:
    """Defragments the atlas of `input` and writes `output` (sheets beside it).

    Options are the `scanatlas defrag` flags with underscores: `solver="slim"`,
    `matching_tolerance=2`, `no_retry=True`, `max_sheet_size=(2048, 1024)`, `sheet_size=4096`,
    `pow2=True`, `texel_scale=0.5`, `config="c.toml"`...
    `progress` is called with each stage's label. Returns the run report.

    Raises ValueError (bad option or plugin), OSError (files), ModelError (bad model).
    """

def build(
    mesh: _Path,
    cameras: _Path,
    images: _Path,
    output: _Path,
    *,
    progress: _Progress = None,
    **options: Any,
) -> dict[str, Any]:
    """Builds a texture atlas from registered photographs (`scanatlas build`); returns the report."""

def stats(path: _Path, *, overlaps: bool = True) -> dict[str, Any]:
    """The atlas figures of a model, as `scanatlas stats --json` prints them."""

def plugins() -> list[dict[str, Any]]:
    """Every plugin with its kind, name, summary and parameters (`scanatlas plugins --json`)."""
