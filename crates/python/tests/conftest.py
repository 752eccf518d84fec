"""Shared fixtures: the repository's paths and the command line, to compare with."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
SCENES = REPO / "fixtures" / "scenes"


#: The level-2 icosphere (162 vertices, 320 faces).
SPHERE_MESH = REPO / "fixtures" / "meshes" / "icosphere-2.obj"

#: That icosphere in centimetres (lengths in the command line's files are in cm), a linear
#: tissue hanging from its cap under gravity, solved by the finite-element method on a
#: coarse grid (a second or so). `.format(mesh=...)` puts the mesh's path in.
SPHERE_FEM_CM = """\
[mesh]
path = "{mesh}"
unit = "cm"
[tissue]
young = 5000.0
poisson = 0.45
density = 1000.0
[gravity]
acceleration = [0.0, -9.81, 0.0]
[[fix]]
axis = "y"
above = 0.8
[solver]
method = "fem"
[fem]
resolution = 8
"""


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `fibfluid` command line: $FIBFLUID_CLI when set, else built here with cargo
    (`cargo build -p fibfluid-cli`, which is quick when the workspace was built before).
    Skips, saying why, when neither is available."""
    exe = os.environ.get("FIBFLUID_CLI")
    if exe:
        if not Path(exe).is_file():
            pytest.fail(f"FIBFLUID_CLI={exe} is not a file")
        return Path(exe)
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.skip("cargo is not on PATH and FIBFLUID_CLI is not set: no command line to compare with")
    built = subprocess.run(
        [cargo, "build", "-q", "-p", "fibfluid-cli", "--bin", "fibfluid", "--message-format=json-render-diagnostics"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        text=True,
    )
    if built.returncode != 0:
        pytest.fail("cargo build -p fibfluid-cli failed (see its output above)")
    for line in built.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg.get("executable"):
            return Path(msg["executable"])
    pytest.fail("cargo build -p fibfluid-cli named no executable")


def run_cli(cli: Path, *args: str) -> subprocess.CompletedProcess:
    """Runs the command line from the repository's root."""
    return subprocess.run([str(cli), *args], cwd=REPO, capture_output=True, text=True)


def read_obj_vertices(path: Path):
    """The `v` lines of an OBJ file, as written (a list of 3-float lists)."""
    out = []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            out.append([float(x) for x in line.split()[1:4]])
    return out
