"""Sphinx configuration of cnc-twin's documentation site.

Build it (warnings are errors; every cross-reference must resolve)::

    python -m sphinx -W -n --keep-going -b html docs docs/_build/html

Why Sphinx (not MkDocs): the package's docstrings are written for it (Sphinx roles such as
``:class:`~cnc_twin.run.twin.Twin``` and ``:func:``; about 1,300 of them), so ``autodoc`` renders
them as written and ``-n`` checks every one; the pages stay Markdown through myst-parser, so the
suite runs their code blocks as it runs the README's (tests/test_docs.py). No inventory is fetched
(nothing reaches the network): references to numpy, MuJoCo and the other dependencies are left as
plain text (``nitpick_ignore_regex`` below).
"""

from __future__ import annotations

import sys
from datetime import date
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(DOCS.parent))  # the checkout's package, where the site is built from a clone

project = "cnc-twin"
author = "the cnc-twin developers"
copyright = f"{date.today().year}, {author}"

extensions = [
    "bench_figures",
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "scenario_reference",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "README.md"]
templates_path = ["_templates"]

myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 4

# Each function and class is not an entry of the site's table of contents: with 220 module pages,
# resolving every page's sidebar over those entries took two thirds of the build (4 min -> see
# CONTRIBUTING for the build's time)
toc_object_entries = False

autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True, "member-order": "bysource"}
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True

nitpicky = True
# The dependencies' own types: their documentation is not fetched (no network), so a reference to
# them stays plain text instead of failing the build
nitpick_ignore_regex = [
    # pydantic fields' constraints (Annotated[float, Field(gt=0)]) rendered in the signatures
    (r"py:class", r"annotated_types\..*|(gt|ge|lt|le|min_length|max_length|multiple_of|pattern|strict|allow_inf_nan|annotation|required|discriminator)=.*"),
    (r"py:.*", r"(np|numpy|npt|numpy\.typing|mujoco|pa|pyarrow|pd|pandas|pydantic|pydantic_core|scipy|control|rr|rerun|yaml|numba|dask|distributed|matplotlib)\..*"),
    (r"py:.*", r"(collections\.abc|collections|typing|os|io|pathlib|subprocess|socket|threading|multiprocessing|concurrent\.futures|enum|dataclasses|argparse|signal|struct|mmap|types|ctypes|selectors|logging|queue|json|re|datetime|contextlib|array|tempfile|select|shutil|itertools|functools|weakref|abc|typing_extensions)\..*"),
    (r"py:class", r"(NDArray|ArrayLike|DTypeLike|Path|Callable|Iterator|Iterable|Sequence|Mapping|Any|Self|TextIO|BinaryIO|IO|Literal|ClassVar|Generator|ndarray|dtype|MjModel|MjData|Table|DataFrame|BaseModel|Enum|IntEnum|IntFlag|StrEnum|Popen|Thread|Event|Lock|socket|datetime|timedelta|Namespace|ArgumentParser|Queue|Connection|Process|Future|deque|TracebackType|FrameType|mmap|Exception|OSError|ValueError|RuntimeError|TimeoutError|KeyError|NamedTuple|TypedDict|ModuleType|CompletedProcess|RecordingStream|Figure|Axes|StateSpace|TransferFunction|LinearIOSystem|NonlinearIOSystem|Client|ConfigDict|FieldInfo|ValidationError|Protocol|Generic|TypeVar|ParamSpec|Iterator\[.*\]|float64|int64|uint8|int32|uint32|bool_)"),
]





def _public_bases(app, name, obj, options, bases):
    """A class's private base (``_PathKind``) is shown as the public classes it derives from: its
    page does not exist, and a reader has nothing to look up in it."""
    shown = []
    for base in bases:
        if base.__name__.startswith("_"):
            shown.extend(b for b in base.__bases__ if b not in shown and b is not object)
        elif base not in shown:
            shown.append(base)
    bases[:] = shown or [object]


def setup(app):
    app.connect("autodoc-process-bases", _public_bases)


html_theme = "furo"
html_title = "cnc-twin"
html_static_path: list[str] = []
