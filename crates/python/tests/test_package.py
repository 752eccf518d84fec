"""The package itself: version, stubs, the lock file."""

from pathlib import Path

import pytest

import fibfluid

tomllib = pytest.importorskip("tomllib", reason="tomllib needs Python 3.11")

CRATE = Path(__file__).resolve().parents[1]
REPO = CRATE.parents[1]


def test_version_matches_the_crate_and_the_workspace():
    crate = tomllib.loads((CRATE / "Cargo.toml").read_text())["package"]["version"]
    workspace = tomllib.loads((REPO / "Cargo.toml").read_text())["workspace"]["package"]["version"]
    assert fibfluid.__version__ == crate == workspace


def test_the_lock_pins_the_workspaces_versions():
    """The package is built outside the workspace, with its own Cargo.lock: every crate it
    shares with the workspace must be the version the command line is built with, or the
    numbers could differ."""

    def versions(path):
        out = {}
        for p in tomllib.loads(path.read_text())["package"]:
            out.setdefault(p["name"], set()).add(p["version"])
        return out

    ours, theirs = versions(CRATE / "Cargo.lock"), versions(REPO / "Cargo.lock")
    shared = set(ours) & set(theirs)
    assert {"faer", "rayon", "nalgebra", "serde_json"} <= shared
    drift = {name: (ours[name], theirs[name]) for name in shared if not ours[name] <= theirs[name]}
    assert drift == {}


def test_every_public_function_has_a_docstring():
    for name in fibfluid.__all__:
        obj = getattr(fibfluid, name)
        if callable(obj):
            assert obj.__doc__, name
    for cls in (fibfluid.Scene, fibfluid.Body, fibfluid.Result, fibfluid.Volume):
        for attr, value in vars(cls).items():
            if not attr.startswith("_") and (callable(value) or isinstance(value, (property, staticmethod))):
                assert getattr(cls, attr).__doc__ or getattr(value, "__doc__", None), f"{cls.__name__}.{attr}"


def test_typing_marker_and_stubs_are_installed():
    root = Path(fibfluid.__file__).parent
    assert (root / "py.typed").is_file()
    assert (root / "_native.pyi").is_file()
    assert (root / "__init__.pyi").is_file()
