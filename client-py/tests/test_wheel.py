"""`pip install echogym` from a wheel: built by maturin (abi3), installed into a clean
virtualenv with no cargo on its PATH, it runs the README's Python snippet (which starts
a private server) and `echogym serve` / `status` / `stop`.

The wheel is built from this checkout (sharing the release target directory with the
bootstrap's build); the clean virtualenv gets its dependencies from PyPI, or from uv's
cache when they were fetched before.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.executable).parent


def _run(cmd, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, (
        f"{cmd} exited {result.returncode}\nstdout:\n{result.stdout[-4000:]}\n"
        f"stderr:\n{result.stderr[-4000:]}"
    )
    return result


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheels")
    _run(
        [
            str(VENV_BIN / "maturin"),
            "build",
            "--release",
            "--locked",
            "-m",
            str(REPO / "client-py" / "Cargo.toml"),
            "--interpreter",
            sys.executable,
            "--out",
            str(out),
        ],
        cwd=REPO,
    )
    wheels = list(out.glob("echogym-*.whl"))
    assert len(wheels) == 1, wheels
    assert "abi3" in wheels[0].name, f"{wheels[0].name} is not an abi3 wheel"
    return wheels[0]


@pytest.fixture(scope="module")
def clean_venv(tmp_path_factory, wheel) -> Path:
    venv = tmp_path_factory.mktemp("venv") / "v"
    _run([str(VENV_BIN / "uv"), "venv", "--quiet", "--python", sys.executable, str(venv)])
    _run(
        [
            str(VENV_BIN / "uv"),
            "pip",
            "install",
            "--quiet",
            "--python",
            str(venv / "bin" / "python"),
            str(wheel),
        ]
    )
    return venv


def _clean_env(venv: Path, location) -> dict[str, str]:
    """No cargo, no checkout on the path: only the clean venv and the system."""
    env = {
        "PATH": f"{venv / 'bin'}:/usr/bin:/bin",
        "HOME": os.environ.get("HOME", "/tmp"),
        "ECHOGYM_IPC_PREFIX": location.prefix,
        "ECHOGYM_IPC_ROOT": location.root,
    }
    return env


def test_the_wheel_carries_no_checkout_paths(clean_venv):
    python = clean_venv / "bin" / "python"
    result = _run(
        [str(python), "-c", "import echogym, echogym._native as n; print(echogym.__file__, n.__file__)"],
        cwd="/",
        env={"PATH": "/usr/bin:/bin"},
    )
    assert str(REPO) not in result.stdout, f"imported from the checkout: {result.stdout}"
    assert "abi3" in result.stdout, result.stdout


def test_readme_snippet_runs_from_the_wheel(clean_venv, ipc, tmp_path):
    readme = (REPO / "README.md").read_text()
    snippet = re.search(r"```python\n(.*?)```", readme, re.S)
    assert snippet, "README has no python snippet"
    code = snippet.group(1)
    assert "gym.make" in code
    script = tmp_path / "snippet.py"
    script.write_text(code + "\nprint('snippet ok')\n")
    result = _run(
        [str(clean_venv / "bin" / "python"), str(script)],
        cwd=tmp_path,
        env=_clean_env(clean_venv, ipc),
        timeout=300,
    )
    assert "snippet ok" in result.stdout


def test_serve_status_stop_from_the_wheel(clean_venv, ipc, tmp_path):
    echogym = str(clean_venv / "bin" / "echogym")
    env = _clean_env(clean_venv, ipc)
    server = subprocess.Popen(
        [echogym, "serve", "--name", "wheel"],
        env=env,
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        deadline = time.monotonic() + 30
        while True:
            status = subprocess.run(
                [echogym, "status", "--name", "wheel", "--json"],
                env=env,
                capture_output=True,
                text=True,
            )
            if status.returncode == 0:
                break
            assert server.poll() is None, f"server exited: {server.stdout.read()}"
            assert time.monotonic() < deadline, f"server did not come up: {status.stderr}"
            time.sleep(0.1)
        assert '"leases"' in status.stdout, status.stdout
        _run([echogym, "stop", "--name", "wheel"], env=env)
        assert server.wait(timeout=15) == 0
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
