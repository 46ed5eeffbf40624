"""How the test legs run pytest: the marker selections and the environments (shared by suite_legs,
installed_package and sanitizer_job).

Not a test module: its functions take build_addon.py as `driver`, for run_teed, addon_env and ROOT.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

# pytest markers (registered in tests/conftest.py): `blender` = the headless Blender suite (PyPI bpy),
# `gui` = Debian's Blender 3.4 (real window under Xvfb, legacy install).
CORE_SELECTION = ["-m", "not blender and not gui"]
# One pytest worker per core (pytest-xdist) for the core suite: hundreds of short, independent tests. The
# Blender legs stay in one process (each installs the extension into its own profile).
PYTEST_WORKERS = ["-n", str(min(os.cpu_count() or 1, 4))]
BLENDER_SELECTION = ["-m", "blender"]
GUI_SELECTION = ["-m", "gui"]
QUICK_SELECTION = ["-m", "not blender and not gui and not slow"]

_CLOSING_LINE = re.compile(r"^(?:=+ )?(\d+ (?:passed|failed|skipped|deselected|error).* in [0-9.]+s.*?)(?: =+)?$")


def installed_env() -> dict:
    """Environment of a test run against the installed nfield (a wheel, or the extension inside Blender):
    tests/conftest.py keeps addon/ off sys.path (NFIELD_TEST_INSTALLED)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["NFIELD_TEST_INSTALLED"] = "1"
    return env


def run_pytest(driver, python: Path, args: list[str], env: dict | None = None, wrapper: list = ()) -> tuple[bool, str]:
    """pytest in a fresh process of `python` (started through `wrapper`, if any); (passed, pytest's closing
    line such as '40 passed in 61s')."""
    code, lines = driver.run_teed([*wrapper, python, "-m", "pytest", *args], env=env or driver.addon_env(),
                                  cwd=driver.ROOT, keep=lambda line: bool(_CLOSING_LINE.match(line.strip())))
    closing = _CLOSING_LINE.match(lines[-1]).group(1) if lines else f"exit {code}"
    if code == 5:
        return False, "no tests collected"
    return code == 0, closing
