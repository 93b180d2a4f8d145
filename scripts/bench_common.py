"""Shared steps of the scripts that time slamkit against another library from Python."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def ensure_venv(venv, packages, script):
    """Re-runs `script` inside the virtualenv `venv`, creating it with `packages` first."""
    venv = Path(venv)
    py = venv / "bin" / "python"
    if Path(sys.prefix).resolve() == venv.resolve():
        return
    if not py.exists():
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "-q", *packages], check=True)
    os.execv(str(py), [str(py), str(script), *sys.argv[1:]])


def build_example(crate, example):
    """Builds a release example of `crate` and returns the path of its executable."""
    subprocess.run(["cargo", "build", "--release", "-q", "-p", crate, "--example", example],
                   cwd=ROOT, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return target / "release" / "examples" / example
