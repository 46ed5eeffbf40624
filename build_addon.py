#!/usr/bin/env python3
"""nfield developer driver: set up the machine, build the native module, run tests, demo, bench.

Standard library only; run it with the system python3 from the repository root:

    python3 build_addon.py setup                  # Debian packages + the virtual environments (idempotent)
    python3 build_addon.py build [--python PATH] [--debug] [--sanitize]
    python3 build_addon.py package                # dist/nfield-<version>-linux-x64.zip (every Blender)
    python3 build_addon.py test                   # every leg: core suite per Python, Blender suite per bpy
                                                  # release, Blender 3.4 window, sanitizers, short fuzz run
    python3 build_addon.py test --quick           # the inner loop: native and core tests, about a minute
    python3 build_addon.py test [pytest args...]  # pytest tests <args> in .venv (+ hardening jobs)
    python3 build_addon.py sanitize [pytest args...]  # ASan/UBSan build + the core suite under it
    python3 build_addon.py fuzz [--seconds N] [TARGET...]  # libFuzzer targets (docs/hardening.md)
    python3 build_addon.py demo                   # setup + build + the main job
    python3 build_addon.py bench [args...]        # setup + build + bench/run.py
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
VENV_PY = VENV / "bin" / "python"
ADDON_DIR = ROOT / "addon"
PACKAGE_DIR = ADDON_DIR / "nfield"
BUILD_ROOT = ROOT / "build"

# The main job that `demo` runs (from the repository root, with PYTHONPATH=addon, in .venv): headless PyPI
# bpy designs a field on the rocker arm, renders out/demo_*.png with Cycles and saves out/demo.blend.
DEMO_COMMAND = ["examples/demo/demo.py", "--out", "out"]

# Debian packages the project needs (build, tests, later Blender/Xvfb and sanitizer/fuzz work).
APT_PACKAGES = [
    "build-essential", "pkg-config", "cmake", "ninja-build",
    "libeigen3-dev", "libspectra-dev", "libsuitesparse-dev", "libopenblas-dev",
    "python3-dev", "python3-venv",          # headers for --python /usr/bin/python3 (Blender 3.4's Python)
    "clang-14", "libclang-rt-14-dev",       # sanitizers / libFuzzer
    "xvfb", "xdotool", "blender",           # real-window Blender tests (Debian Blender 3.4, system Python)
    "python3-numpy",                        # NumPy for Debian's Python / Blender 3.4 (not pulled in by blender)
    "ccache",                               # the per-Python builds share the library's objects
]

# The Python environments (virtual environments created by `setup`). Every supported Blender release is tested
# headless through its PyPI `bpy` wheel, which only installs into the CPython that release bundles:
#   Blender 4.2 LTS, 4.5 LTS, 5.0: CPython 3.11, numpy 1.x;  Blender 5.1, 5.2 LTS: CPython 3.13, numpy 2.
# A compiled module is built for each Python version that has a `builds` environment; the extension zip
# carries all of them side by side (Python imports the one whose ABI tag matches it).
TEST_REQUIREMENTS = ("pytest>=7", "pytest-xdist", "hypothesis")


@dataclass(frozen=True)
class PythonEnv:
    name: str                      # as printed in summaries
    folder: Path
    python: tuple[int, int]
    requirements: tuple[str, ...]
    bpy: str                       # the PyPI bpy release installed there (its headless Blender suite runs there)
    builds: bool = False           # the native module is built with this interpreter
    core_suite: bool = False       # the core suite (native math, CLI, sessions) runs there

    @property
    def python_path(self) -> Path:
        return self.folder / "bin" / "python"

    @property
    def version(self) -> str:
        return "%d.%d" % self.python


MAIN_ENV = PythonEnv(
    "main", ROOT / ".venv", (3, 11),
    ("bpy==5.0.1", "numpy>=1.24,<2", "pybind11>=2.11", *TEST_REQUIREMENTS,
     "matplotlib<3.10"),  # bench/ writes the Fig. 8 plot
    bpy="5.0.1", builds=True, core_suite=True)
PY313_ENV = PythonEnv(
    "py313", ROOT / ".venv-313", (3, 13),
    ("bpy==5.2.3", "numpy>=2", "pybind11>=2.11", *TEST_REQUIREMENTS),
    bpy="5.2.3", builds=True, core_suite=True)
BLENDER_ENVS_DIR = ROOT / ".venv-blender"
EXTRA_BPY_ENVS = tuple(
    PythonEnv(f"bpy-{v}", BLENDER_ENVS_DIR / v, (3, 11), (f"bpy=={v}", "numpy>=1.24,<2", *TEST_REQUIREMENTS), bpy=v)
    for v in ("4.2.23", "4.5.15"))
ALL_ENVS = (MAIN_ENV, PY313_ENV, *EXTRA_BPY_ENVS)
VENV = MAIN_ENV.folder
VENV_PY = MAIN_ENV.python_path


class Failure(Exception):
    """An expected failure: printed as one readable message, no traceback."""

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


def say(message: str) -> None:
    print(f"[build_addon] {message}", flush=True)


def _shown(arg: str) -> str:
    """How an argument is printed: paths inside the repository relative to it, scripts elided."""
    if "\n" in arg:
        return "<script>"
    prefix = str(ROOT) + os.sep
    return arg[len(prefix):] if arg.startswith(prefix) else arg


def run(cmd, *, env=None, cwd=ROOT, check=True, capture=False, quiet=False):
    """Run a command, printing it first. Raises Failure on a non-zero exit when check is set."""
    cmd = [str(c) for c in cmd]
    if not quiet:
        print("+ " + " ".join(_shown(c) if "\n" in c else shlex.quote(_shown(c)) for c in cmd), flush=True)
    try:
        proc = subprocess.run(cmd, env=env, cwd=cwd, stdin=subprocess.DEVNULL,
                              capture_output=capture, text=True)
    except FileNotFoundError:
        raise Failure(f"command not found: {cmd[0]}")
    if check and proc.returncode != 0:
        details = ""
        if capture and (proc.stderr or proc.stdout):
            details = "\n" + (proc.stderr or proc.stdout).strip()
        raise Failure(f"command failed (exit {proc.returncode}): {shlex.join(cmd)}{details}")
    return proc


# ---------------------------------------------------------------------------------------- setup

def missing_debian_packages() -> list[str]:
    if shutil.which("dpkg-query") is None:
        return []
    proc = run(["dpkg-query", "-W", "-f=${Package} ${db:Status-Status}\\n", *APT_PACKAGES],
               check=False, capture=True)
    installed = set()
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1] == "installed":
            installed.add(parts[0].split(":")[0])
    return [p for p in APT_PACKAGES if p not in installed]


def setup_debian() -> None:
    if shutil.which("dpkg-query") is None or shutil.which("apt-get") is None:
        say("not a Debian system (no dpkg-query/apt-get): install these yourself: " + " ".join(APT_PACKAGES))
        return
    missing = missing_debian_packages()
    if not missing:
        say(f"Debian packages: all {len(APT_PACKAGES)} installed")
        return
    say("Debian packages missing: " + " ".join(missing))
    prefix = []
    if os.geteuid() != 0:
        if shutil.which("sudo") is None:
            raise Failure("not root and no sudo: install as root: apt-get install " + " ".join(missing))
        prefix = ["sudo"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    # sudo resets the environment; pass DEBIAN_FRONTEND on its command line as well.
    front = prefix + (["DEBIAN_FRONTEND=noninteractive"] if prefix else [])
    run(front + ["apt-get", "update", "-q"], env=env)
    run(front + ["apt-get", "install", "-y", "-q", "-o", "Dpkg::Use-Pty=0", *missing], env=env)
    still = missing_debian_packages()
    if still:
        raise Failure("apt-get did not install: " + " ".join(still))


def _runs_as(python: str, version: tuple[int, int]) -> bool:
    """True if `python` starts and is that version (a pyenv shim for an unselected version does not start)."""
    try:
        proc = subprocess.run([python, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                              capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return proc.returncode == 0 and proc.stdout.strip() == "%d.%d" % version


def find_interpreter(version: tuple[int, int]) -> str | None:
    """A CPython of `version` to create a virtual environment from: this one, pythonX.Y on PATH, a pyenv
    installation (`pyenv prefix`), or the usual system locations. None if there is none."""
    if sys.version_info[:2] == version:
        return sys.executable
    name = "python%d.%d" % version
    candidates = [shutil.which(name)]
    pyenv = shutil.which("pyenv")
    if pyenv:
        listed = subprocess.run([pyenv, "versions", "--bare"], capture_output=True, text=True, check=False).stdout
        releases = [v for v in listed.split() if v.startswith("%d.%d." % version) and v.replace(".", "").isdigit()]
        for release in sorted(releases, key=lambda v: [int(x) for x in v.split(".")], reverse=True):
            prefix = subprocess.run([pyenv, "prefix", release], capture_output=True, text=True, check=False)
            if prefix.returncode == 0:
                candidates.append(os.path.join(prefix.stdout.strip(), "bin", name))
    root = os.environ.get("PYENV_ROOT", os.path.expanduser("~/.pyenv"))
    candidates += sorted(Path(root, "versions").glob("%d.%d.*/bin/%s" % (*version, name)), reverse=True)
    candidates += [f"/usr/bin/{name}", f"/usr/local/bin/{name}"]
    for candidate in candidates:
        if candidate and os.path.exists(candidate) and _runs_as(str(candidate), version):
            return str(candidate)
    return None


# Runs inside .venv: exit 0 when every requirement is installed and satisfied.
_CHECK_REQUIREMENTS = r"""
import sys
from importlib import metadata
try:
    from pip._vendor.packaging.requirements import Requirement
except Exception:
    from packaging.requirements import Requirement
bad = []
for spec in sys.argv[1:]:
    req = Requirement(spec)
    try:
        version = metadata.version(req.name)
    except metadata.PackageNotFoundError:
        bad.append(f"{spec} (not installed)")
        continue
    if req.specifier and not req.specifier.contains(version, prereleases=True):
        bad.append(f"{spec} (have {version})")
print("; ".join(bad))
sys.exit(1 if bad else 0)
"""


def setup_env(env: PythonEnv) -> bool:
    """Creates `env` if needed and installs what is missing. Returns False (after one line saying so) when
    its Python is not on this machine and it is optional; under CI=true that is an error."""
    py = env.python_path
    rel = env.folder.relative_to(ROOT)
    if env.folder.exists() and not py.exists():
        raise Failure(f"{rel} exists but has no bin/python: remove it and run setup again")
    if not py.exists():
        base = find_interpreter(env.python)
        if base is None:
            what = (f"no CPython {env.version} found (not on PATH as python{env.version}, not in pyenv): "
                    f"{rel} is not created, so the Python {env.version} legs (module build, core suite, "
                    f"bpy {env.bpy}) are skipped")
            if env is MAIN_ENV or os.environ.get("CI", "").lower() == "true":
                raise Failure(what)
            say(what)
            return False
        env.folder.parent.mkdir(parents=True, exist_ok=True)
        run([base, "-m", "venv", env.folder])
    proc = run([py, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"], capture=True, quiet=True)
    if proc.stdout.strip() != env.version:
        raise Failure(f"{rel} uses Python {proc.stdout.strip()}, but bpy {env.bpy} needs {env.version}: "
                      f"remove {rel} and run setup again")
    check = run([py, "-c", _CHECK_REQUIREMENTS, *env.requirements], check=False, capture=True, quiet=True)
    if check.returncode == 0:
        say(f"{rel} (Python {env.version}): all {len(env.requirements)} requirements satisfied")
        return True
    say(f"{rel}: to install: " + (check.stdout.strip() or check.stderr.strip().splitlines()[-1]))
    run([py, "-m", "pip", "install", "--disable-pip-version-check", "--progress-bar", "off",
         "--no-input", *env.requirements])
    check = run([py, "-c", _CHECK_REQUIREMENTS, *env.requirements], check=False, capture=True)
    if check.returncode != 0:
        raise Failure(f"pip did not satisfy in {rel}: " + check.stdout.strip())
    say(f"{rel} (Python {env.version}): installed, all {len(env.requirements)} requirements satisfied")
    return True


def ready_envs() -> list[PythonEnv]:
    """The environments that exist and have their interpreter (after setup)."""
    return [env for env in ALL_ENVS if env.python_path.exists()]


def link_addon_into_venv() -> None:
    """Make `nfield` importable from .venv (so `.venv/bin/python -m nfield` works from anywhere)
    through a .pth file naming addon/, the package's source folder (no copy to go stale)."""
    proc = run([VENV_PY, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], capture=True, quiet=True)
    pth = Path(proc.stdout.strip()) / "nfield-addon.pth"
    if not pth.exists() or pth.read_text().strip() != str(ADDON_DIR):
        pth.write_text(str(ADDON_DIR) + "\n")
        say(f"linked {ADDON_DIR} into .venv ({pth.name})")


def cmd_setup(_args=None) -> int:
    setup_debian()
    for env in ALL_ENVS:
        setup_env(env)
    link_addon_into_venv()
    return 0


# ---------------------------------------------------------------------------------------- build

_INTERPRETER_INFO = r"""
import json, os, platform, sys, sysconfig
inc = sysconfig.get_paths().get("include") or ""
print(json.dumps({
    "executable": sys.executable,
    "implementation": sys.implementation.name,
    "version": platform.python_version(),
    "include": inc,
    "has_headers": os.path.isfile(os.path.join(inc, "Python.h")),
    "ext_suffix": sysconfig.get_config_var("EXT_SUFFIX"),
}))
"""


def interpreter_info(python: str) -> dict:
    path = shutil.which(python) if os.sep not in python else python
    if not path or not os.path.exists(path):
        raise Failure(f"interpreter not found: {python}")
    proc = run([path, "-c", _INTERPRETER_INFO], capture=True, check=False)
    if proc.returncode != 0:
        raise Failure(f"could not query interpreter {path}: {(proc.stderr or '').strip()}")
    info = json.loads(proc.stdout)
    info["path"] = os.path.abspath(path)
    if not info["ext_suffix"]:
        raise Failure(f"{path} reports no EXT_SUFFIX; cannot build an extension module for it")
    if not info["has_headers"]:
        raise Failure(f"{path} (Python {info['version']}) has no C headers: {info['include']}/Python.h "
                      "is missing. On Debian install python3-dev (or python3.X-dev) for it.")
    return info


def pybind11_cmake_dir() -> str:
    if not VENV_PY.exists():
        raise Failure("no .venv: run `python3 build_addon.py setup` first")
    proc = run([VENV_PY, "-m", "pybind11", "--cmakedir"], capture=True, check=False, quiet=True)
    if proc.returncode != 0:
        raise Failure("pybind11 is not installed in .venv: run `python3 build_addon.py setup` first")
    return proc.stdout.strip()


def check_sources() -> None:
    if not (ROOT / "native" / "python" / "module.cpp").is_file():
        raise Failure("native/python/module.cpp does not exist (nothing to build yet)")
    if not list((ROOT / "native" / "src").glob("*.cpp")):
        raise Failure("native/src/*.cpp: no sources (nothing to build yet)")


def check_no_numpy_headers(build_dir: Path) -> None:
    """The module must never be compiled against NumPy's C headers (ABI differs between NumPy builds)."""
    db = build_dir / "compile_commands.json"
    if not db.exists():
        return
    for entry in json.loads(db.read_text()):
        command = entry.get("command") or " ".join(entry.get("arguments", []))
        for token in shlex.split(command):
            if token.startswith(("-I", "-isystem")) and "numpy" in token.lower():
                raise Failure(f"{entry.get('file')} is compiled with NumPy's headers ({token}); "
                              "the module must not depend on NumPy's C API")
            if "numpy/core/include" in token or "numpy/_core/include" in token:
                raise Failure(f"{entry.get('file')} is compiled with NumPy's headers ({token})")


def build_tag(info: dict, variant: str) -> str:
    """Build directory name under build/: one per interpreter and variant."""
    return f"{info['implementation']}-{info['version']}-{variant}"


def build(python: str | None = None, debug: bool = False, sanitize: bool = False) -> Path:
    """Configure + build; returns the path of the built module (copied into addon/nfield unless sanitize)."""
    check_sources()
    cmake = shutil.which("cmake")
    if cmake is None:
        raise Failure("cmake not found: run `python3 build_addon.py setup` first")
    info = interpreter_info(python or str(VENV_PY))
    pybind11_dir = pybind11_cmake_dir()

    build_type = "Debug" if debug else ("RelWithDebInfo" if sanitize else "Release")
    variant = ("asan-" if sanitize else "") + ("debug" if debug else "release")
    build_dir = BUILD_ROOT / build_tag(info, variant)
    generator = "Ninja" if shutil.which("ninja") else "Unix Makefiles"

    config = {
        "CMAKE_BUILD_TYPE": build_type,
        "NFIELD_SANITIZE": "ON" if sanitize else "OFF",
        "pybind11_DIR": pybind11_dir,
        "Python_EXECUTABLE": info["path"],
        "Python_INCLUDE_DIR": info["include"],
        "PYTHON_MODULE_EXTENSION": info["ext_suffix"],
    }
    if shutil.which("ccache"):
        config["CMAKE_CXX_COMPILER_LAUNCHER"] = "ccache"
    stamp = build_dir / "nfield-config.json"
    wanted = {"generator": generator, "cmake": cmake, **config}
    build_file = build_dir / ("build.ninja" if generator == "Ninja" else "Makefile")
    previous = json.loads(stamp.read_text()) if stamp.exists() else None
    if previous != wanted or not build_file.exists():
        if previous is not None and previous != wanted:
            say(f"configuration changed, reconfiguring {build_dir.relative_to(ROOT)} from scratch")
            (build_dir / "CMakeCache.txt").unlink(missing_ok=True)
            shutil.rmtree(build_dir / "CMakeFiles", ignore_errors=True)
        build_dir.mkdir(parents=True, exist_ok=True)
        run([cmake, "-S", ROOT, "-B", build_dir, "-G", generator,
             *[f"-D{k}={v}" for k, v in config.items()]])
        stamp.write_text(json.dumps(wanted, indent=1) + "\n")
    build_cmd = [cmake, "--build", build_dir]
    if generator != "Ninja":
        build_cmd += ["--parallel", str(os.cpu_count() or 2)]
    # ccache hashes paths relative to the checkout, so clones and worktrees share one cache.
    try:
        run(build_cmd, env=dict(os.environ, CCACHE_BASEDIR=str(ROOT)))
    except Failure:
        stamp.unlink(missing_ok=True)  # reconfigure next time, in case the configuration was the problem
        raise
    check_no_numpy_headers(build_dir)

    module = build_dir / f"_native{info['ext_suffix']}"
    if not module.is_file():
        raise Failure(f"the build did not produce {module}")
    if sanitize:
        say(f"sanitizer build (not copied into addon/): {module}")
        say("to use it, put it in a copy of addon/nfield and run Python with "
            "LD_PRELOAD=\"$(gcc -print-file-name=libasan.so) $(gcc -print-file-name=libubsan.so)\" "
            "ASAN_OPTIONS=detect_leaks=0")
        return module
    PACKAGE_DIR.mkdir(parents=True, exist_ok=True)
    dest = PACKAGE_DIR / module.name
    tmp = dest.with_name(dest.name + ".tmp")
    shutil.copy2(module, tmp)
    os.replace(tmp, dest)  # atomic: a process that has the old file mapped keeps working
    say(f"built {module.relative_to(ROOT)} -> {dest.relative_to(ROOT)} (Python {info['version']}, {build_type})")
    return module


def build_all(debug: bool = False) -> list[Path]:
    """Builds the module for every interpreter set up to build one (one build directory each)."""
    return [build(str(env.python_path), debug) for env in ready_envs() if env.builds]


def cmd_build(args) -> int:
    if args.python or args.sanitize:
        build(args.python, args.debug, args.sanitize)
    else:
        build_all(args.debug)
    return 0


# ---------------------------------------------------------------------------------------- run things

def addon_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ADDON_DIR), env.get("PYTHONPATH", "")) if p)
    return env


class Legs:
    """The legs of a test run, each timed; `summary()` prints one line per leg (ok/FAILED, what, time)."""

    def __init__(self):
        self.rows: list[tuple[str, bool, str]] = []

    def run(self, title: str, job) -> bool:
        """Runs job() -> (ok, detail) or raises Failure; records the outcome and its wall time."""
        import time

        start = time.monotonic()
        try:
            ok, detail = job()
        except Failure as exc:
            print(f"build_addon: error: {exc}", file=sys.stderr, flush=True)
            ok, detail = False, "FAILED"
        self.rows.append((title, ok, f"{detail} in {time.monotonic() - start:.0f} s"))
        return ok

    def skip(self, title: str, reason: str) -> None:
        self.rows.append((title, True, f"skipped: {reason}"))

    def summary(self) -> bool:
        say("summary:")
        for title, ok, detail in self.rows:
            say(f"  {'ok    ' if ok else 'FAILED'}  {title}: {detail}")
        return all(ok for _, ok, _ in self.rows)


def run_pytest(python: Path, args: list[str], env: dict | None = None) -> tuple[bool, str]:
    """pytest in a fresh process of `python`; (passed, pytest's closing line such as '40 passed in 61s')."""
    import re

    closing_line = re.compile(r"^(?:=+ )?(\d+ (?:passed|failed|skipped|deselected|error).* in [0-9.]+s.*?)(?: =+)?$")
    code, lines = run_teed([python, "-m", "pytest", *args], env=env or addon_env(), cwd=ROOT,
                           keep=lambda line: bool(closing_line.match(line.strip())))
    closing = closing_line.match(lines[-1]).group(1) if lines else f"exit {code}"
    if code == 5:
        return False, "no tests collected"
    return code == 0, closing


# pytest markers (registered in tests/conftest.py): `blender` = the headless Blender suite (PyPI bpy),
# `gui` = Debian's Blender 3.4 (real window under Xvfb, legacy install).
CORE_SELECTION = ["-m", "not blender and not gui"]
BLENDER_SELECTION = ["-m", "blender"]
GUI_SELECTION = ["-m", "gui"]


def cmd_test(pytest_args: list[str]) -> int:
    """The whole test suite, leg by leg (see Legs): set-up, builds and the zip, C++ tests, the core suite
    under each Python, the headless Blender suite under each bpy release, the real-window tests, then the
    sanitizer job and a short fuzz run. With pytest arguments: only `pytest tests <args>` in .venv (plus the
    hardening jobs unless NFIELD_SKIP_HARDENING=1)."""
    if pytest_args[:1] == ["--"]:  # `build_addon.py test -- -k foo`: the separator is not for pytest
        pytest_args = pytest_args[1:]
    if pytest_args[:1] == ["--quick"]:
        return cmd_quick_test(pytest_args[1:])
    legs = Legs()
    legs.run("setup", lambda: (cmd_setup() == 0, "done"))
    envs = ready_envs()
    if not legs.run("build and package", lambda: (cmd_package(argparse.Namespace(python=None)) == 0,
                                                   f"modules for Python {', '.join(e.version for e in envs if e.builds)}")):
        legs.summary()
        return 1
    if pytest_args:
        names_paths = any(not a.startswith("-") and Path(a.split("::")[0]).exists() for a in pytest_args)
        legs.run("pytest " + " ".join(pytest_args),
                 lambda: run_pytest(VENV_PY, ([] if names_paths else ["tests"]) + pytest_args))
        return run_hardening_jobs(legs)
    ctest_dir = BUILD_ROOT / build_tag(interpreter_info(str(VENV_PY)), "release")
    if (ctest_dir / "CTestTestfile.cmake").exists():  # C++ tests (native/tests/*.cpp)
        legs.run("C++ tests (ctest)", lambda: (run(["ctest", "--test-dir", ctest_dir, "--output-on-failure"],
                                                   check=False).returncode == 0, "ctest"))
    for env in envs:
        if env.core_suite:
            legs.run(f"core suite, Python {env.version}", lambda env=env: run_pytest(env.python_path,
                                                                                     ["tests", *CORE_SELECTION]))
    for env in sorted(envs, key=lambda e: [int(x) for x in e.bpy.split(".")]):
        legs.run(f"headless Blender suite, bpy {env.bpy} (Python {env.version})",
                 lambda env=env: run_pytest(env.python_path, ["tests", *BLENDER_SELECTION]))
    missing = [e for e in ALL_ENVS if e not in envs]
    for env in missing:
        legs.skip(f"Python {env.version} legs (bpy {env.bpy})", f"no CPython {env.version} on this machine")
    legs.run("Debian Blender 3.4 (real window, legacy install)",
             lambda: run_pytest(VENV_PY, ["tests", *GUI_SELECTION]))
    return run_hardening_jobs(legs)


def cmd_quick_test(pytest_args: list[str]) -> int:
    """The inner loop (about a minute): build for .venv's Python only, the C++ tests, and the core suite
    without the `slow` tests; no zip, no Blender, no hardening jobs."""
    legs = Legs()
    legs.run("setup", lambda: (cmd_setup() == 0, "done"))
    module = build()
    if (module.parent / "CTestTestfile.cmake").exists():
        legs.run("C++ tests (ctest)", lambda: (run(["ctest", "--test-dir", module.parent, "--output-on-failure"],
                                                   check=False).returncode == 0, "ctest"))
    # One pytest worker per core (pytest-xdist): the suite is hundreds of short, independent tests.
    workers = ["-n", str(min(os.cpu_count() or 1, 4))]
    legs.run("core suite without slow tests, Python %s" % MAIN_ENV.version,
             lambda: run_pytest(VENV_PY, ["tests", "-q", *workers, "-m", "not blender and not gui and not slow",
                                          *pytest_args]))
    return 0 if legs.summary() else 1


def run_hardening_jobs(legs: Legs) -> int:
    """After the pytest legs: the sanitizer job and a short fuzz run (docs/hardening.md), each timed, then
    the summary of every leg. Runs even when a leg failed, so one CI run reports everything.
    NFIELD_SKIP_HARDENING=1 skips both (fast local iteration; CI never sets it)."""
    if os.environ.get("NFIELD_SKIP_HARDENING", "") not in ("", "0"):
        say("NFIELD_SKIP_HARDENING is set: skipping the sanitizer job and the fuzz run")
    else:
        legs.run("sanitizer job (ASan/UBSan pytest)", lambda: (cmd_sanitize([]) == 0, "passed"))
        legs.run(f"fuzz run ({FUZZ_SECONDS_IN_TEST} s per target)",
                 lambda: (cmd_fuzz(argparse.Namespace(seconds=FUZZ_SECONDS_IN_TEST, targets=[])) == 0, "passed"))
    return 0 if legs.summary() else 1


def cmd_demo(_args) -> int:
    cmd_setup()
    build()
    (ROOT / "out").mkdir(exist_ok=True)
    proc = run([VENV_PY, *DEMO_COMMAND], env=addon_env(), check=False)
    if proc.returncode != 0:
        raise Failure(f"demo failed (exit {proc.returncode})", proc.returncode)
    return 0


def cmd_bench(bench_args: list[str]) -> int:
    script = ROOT / "bench" / "run.py"
    if not script.is_file():
        raise Failure("bench/run.py does not exist yet")
    cmd_setup()
    build()
    return run([VENV_PY, script, *bench_args], env=addon_env(), check=False).returncode


# ---------------------------------------------------------------------------------------- sanitizers

# What the sanitizer job runs: the core suite (no bpy, no Debian Blender) without the tests marked `slow`
# (the same code paths as the rest on 20k-70k face meshes, about 6x slower under ASan/UBSan) or
# `no_sanitizer` (they run no native code, or measure memory and address-space limits, which ASan changes).
SANITIZER_SELECTION = ["-m", "not blender and not gui and not slow and not no_sanitizer"]


def gcc_runtime(name: str) -> str:
    """Absolute path of gcc's sanitizer runtime (libasan.so / libubsan.so), which the module links."""
    path = run(["gcc", f"-print-file-name={name}"], capture=True, quiet=True).stdout.strip()
    if not os.path.isabs(path) or not os.path.exists(path):
        raise Failure(f"gcc has no {name} (Debian: apt-get install gcc; it ships with gcc 12)")
    return path


def sanitizer_tree(module: Path) -> Path:
    """A throw-away mirror of the repository layout next to the sanitizer build: addon/nfield (package
    sources plus the sanitized module, never the normal one) and tests/ (the test files; data/ and
    examples/ linked). The tests find addon/ relative to their own file, so they and the CLI subprocesses
    they start import the sanitized package, not the working copy's."""
    tree = module.parent / "pytree"
    shutil.rmtree(tree, ignore_errors=True)
    shutil.copytree(PACKAGE_DIR, tree / "addon" / "nfield",
                    ignore=shutil.ignore_patterns("__pycache__", "_native*", "*.tmp", "libs"))
    shutil.copy2(module, tree / "addon" / "nfield" / module.name)
    (tree / "tests").mkdir()
    for path in (ROOT / "tests").glob("*.py"):
        shutil.copy2(path, tree / "tests" / path.name)
    (tree / "tests" / "data").symlink_to(ROOT / "tests" / "data")
    (tree / "examples").symlink_to(ROOT / "examples")
    return tree


def sanitizer_env(tree: Path, module: Path) -> dict:
    """Environment of the sanitized test run. Every ASan/UBSan report aborts the process that hit it
    (halt_on_error + abort_on_error, and the module is built with -fno-sanitize-recover=all): the pytest
    process then dies with SIGABRT, and a CLI subprocess that a test starts exits with -6, which no test
    expects. Leak detection is off: CPython does not free everything at exit by design, and those
    reports would drown any real one (the fuzzers keep LeakSanitizer on for the library)."""
    env = addon_env()
    env["PYTHONPATH"] = os.pathsep.join([str(tree / "addon"), str(tree / "tests")])
    env["LD_PRELOAD"] = " ".join([gcc_runtime("libasan.so"), gcc_runtime("libubsan.so")])
    env["ASAN_OPTIONS"] = "detect_leaks=0:halt_on_error=1:abort_on_error=1:check_initialization_order=1"
    env["UBSAN_OPTIONS"] = "halt_on_error=1:abort_on_error=1:print_stacktrace=1"
    env["NFIELD_SANITIZED_MODULE"] = str(tree / "addon" / "nfield" / module.name)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


# A line with one of these in the output of the sanitized run is a sanitizer report.
SANITIZER_REPORT_MARKERS = ("ERROR: AddressSanitizer", "SUMMARY: AddressSanitizer", "runtime error:",
                            "SUMMARY: UndefinedBehaviorSanitizer")


def run_teed(cmd, *, env, cwd, keep=lambda line: False) -> tuple[int, list[str]]:
    """Runs cmd with its output passed through to ours line by line; returns (exit code, the lines for
    which keep(line) is true)."""
    print("+ " + " ".join(shlex.quote(_shown(str(c))) for c in cmd), flush=True)
    kept = []
    with subprocess.Popen([str(c) for c in cmd], env=env, cwd=cwd, stdin=subprocess.DEVNULL,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors="replace") as proc:
        for line in proc.stdout:
            sys.stdout.write(line)
            if keep(line):
                kept.append(line.strip())
        sys.stdout.flush()
    return proc.returncode, kept


def is_sanitizer_report(line: str) -> bool:
    return any(marker in line for marker in SANITIZER_REPORT_MARKERS)


def cmd_sanitize(pytest_args: list[str]) -> int:
    """Builds the ASan/UBSan module and runs the core suite against it (see SANITIZER_SELECTION).
    Fails on a pytest failure (including the abort a report causes) or a report line in the output."""
    import time

    start = time.monotonic()
    module = build(sanitize=True)
    built = time.monotonic()
    tree = sanitizer_tree(module)
    # --capture=sys: pytest's default fd capture would swallow a report written to fd 2 by the runtime
    # (the process aborts before the captured text is shown); sys capture leaves fd 2 alone.
    cmd = [VENV_PY, "-m", "pytest", "-p", "sanitized_module_check", "-p", "no:cacheprovider", "-q",
           "--capture=sys", "--durations=10", *SANITIZER_SELECTION, str(tree / "tests"), *pytest_args]
    code, reports = run_teed(cmd, env=sanitizer_env(tree, module), cwd=tree, keep=is_sanitizer_report)
    end = time.monotonic()
    say(f"sanitizer job: build {built - start:.0f} s, tests {end - built:.0f} s, pytest exit {code}, "
        f"{len(reports)} sanitizer report line(s)")
    if reports:
        raise Failure("sanitizer report(s) in the output above:\n  " + "\n  ".join(reports[:10]))
    if code != 0:
        how = f"killed by signal {-code} (a sanitizer abort?)" if code < 0 else f"exit {code}"
        raise Failure(f"pytest under ASan/UBSan failed ({how})", 1)
    return 0


# ---------------------------------------------------------------------------------------- fuzzing

FUZZ_DIR = ROOT / "native" / "fuzz"
FUZZ_BUILD = BUILD_ROOT / "fuzz-clang14"
FUZZ_WORK = BUILD_ROOT / "fuzz"
# target -> libFuzzer options of its own: the file targets take inputs up to 4 kB (headers plus a few
# dozen elements), the ingestion target decodes at most 24 vertices and 48 faces (< 1 kB).
FUZZ_TARGETS = {
    "parse_obj": ["-max_len=4096", f"-dict={FUZZ_DIR / 'dict' / 'obj.dict'}"],
    "parse_off": ["-max_len=4096", f"-dict={FUZZ_DIR / 'dict' / 'off.dict'}"],
    "parse_ply": ["-max_len=4096", f"-dict={FUZZ_DIR / 'dict' / 'ply.dict'}"],
    "mesh_ingestion": ["-max_len=1024"],
}
FUZZ_SECONDS_IN_TEST = 45
# A single input slower than this is a finding (a hang); memory beyond the limit too.
FUZZ_TIMEOUT_SECONDS = 10
FUZZ_RSS_LIMIT_MB = 2048


def build_fuzzers() -> Path:
    """Configures (once) and builds native/fuzz with clang++-14 into build/fuzz-clang14."""
    clang = shutil.which("clang++-14")
    if clang is None:
        raise Failure("clang++-14 not found: run `python3 build_addon.py setup` (Debian clang-14, libclang-rt-14-dev)")
    generator = "Ninja" if shutil.which("ninja") else "Unix Makefiles"
    build_file = FUZZ_BUILD / ("build.ninja" if generator == "Ninja" else "Makefile")
    if not build_file.exists():
        FUZZ_BUILD.mkdir(parents=True, exist_ok=True)
        run(["cmake", "-S", ROOT, "-B", FUZZ_BUILD, "-G", generator, f"-DCMAKE_CXX_COMPILER={clang}",
             "-DCMAKE_BUILD_TYPE=Debug", "-DNFIELD_FUZZ=ON", "-DNFIELD_BUILD_PYTHON=OFF"])
    cmd = ["cmake", "--build", FUZZ_BUILD, "--target", "nfield_fuzzers"]
    if generator != "Ninja":
        cmd += ["--parallel", str(os.cpu_count() or 2)]
    run(cmd)
    return FUZZ_BUILD


def libfuzzer_stats(output: str) -> dict:
    """The stat::name: value lines of -print_final_stats=1."""
    stats = {}
    for line in output.splitlines():
        if line.startswith("stat::"):
            key, _, value = line[len("stat::"):].partition(":")
            stats[key.strip()] = value.strip()
    return stats


def run_fuzz_target(name: str, seconds: int, build_dir: Path) -> tuple[bool, str]:
    """Runs one target for `seconds` on its seeds (native/fuzz/corpus/<name>, always replayed first) plus
    the inputs earlier runs found (build/fuzz/corpus/<name>, where new ones are written). Returns
    (ok, summary line). A finding's input is saved under build/fuzz/findings/<name>/."""
    binary = build_dir / f"fuzz_{name}"
    seeds = FUZZ_DIR / "corpus" / name
    work = FUZZ_WORK / "corpus" / name
    findings = FUZZ_WORK / "findings" / name
    work.mkdir(parents=True, exist_ok=True)
    findings.mkdir(parents=True, exist_ok=True)
    log = FUZZ_WORK / f"{name}.log"
    cmd = [binary, f"-max_total_time={seconds}", f"-timeout={FUZZ_TIMEOUT_SECONDS}",
           f"-rss_limit_mb={FUZZ_RSS_LIMIT_MB}", "-print_final_stats=1", f"-artifact_prefix={findings}/",
           *FUZZ_TARGETS[name], work, seeds]
    print("+ " + " ".join(shlex.quote(_shown(str(c))) for c in cmd) + f"  > {_shown(str(log))}", flush=True)
    with open(log, "w") as out:
        proc = subprocess.run([str(c) for c in cmd], stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
    output = log.read_text(errors="replace")
    stats = libfuzzer_stats(output)
    runs, speed = stats.get("number_of_executed_units", "?"), stats.get("average_exec_per_sec", "?")
    summary = f"{name}: {runs} runs, {speed} exec/s, exit {proc.returncode}"
    if proc.returncode == 0:
        return True, summary
    # Show the report (libFuzzer prints the sanitizer report and the artifact path) and how to replay it.
    tail = output.splitlines()[-60:]
    print("\n".join(tail), flush=True)
    artifacts = sorted(findings.glob("*"), key=lambda p: p.stat().st_mtime)
    if artifacts:
        say(f"{name}: finding saved as {_shown(str(artifacts[-1]))}; reproduce with:\n"
            f"    {_shown(str(binary))} {_shown(str(artifacts[-1]))}")
    return False, summary + f" FINDING (log {_shown(str(log))})"


def cmd_fuzz(args) -> int:
    """Builds the fuzzers and runs the chosen targets one after the other; fails if any found something."""
    import time

    names = args.targets or list(FUZZ_TARGETS)
    unknown = [n for n in names if n not in FUZZ_TARGETS]
    if unknown:
        raise Failure(f"unknown fuzz target(s) {', '.join(unknown)}; targets: {', '.join(FUZZ_TARGETS)}")
    if args.seconds < 1:
        raise Failure("--seconds must be at least 1")
    start = time.monotonic()
    build_dir = build_fuzzers()
    built = time.monotonic()
    results = [run_fuzz_target(name, args.seconds, build_dir) for name in names]
    say(f"fuzz job: build {built - start:.0f} s, fuzzing {time.monotonic() - built:.0f} s")
    for ok, line in results:
        say(("  ok       " if ok else "  FAILED   ") + line)
    failed = [line for ok, line in results if not ok]
    if failed:
        raise Failure(f"{len(failed)} fuzz target(s) found a problem (see above)")
    return 0


# Libraries every Linux system (and Blender) provides: never bundled (manylinux policy).
PACKAGE_SYSTEM_LIBS = ("linux-vdso", "ld-linux", "libc.so", "libm.so", "libdl.so", "libpthread.so", "librt.so",
                       "libstdc++.so", "libgcc_s.so", "libutil.so")
# Never packaged: generated, caches, development-only files.
PACKAGE_EXCLUDE_DIRS = {"__pycache__", "libs"}
PACKAGE_EXCLUDE_SUFFIXES = (".pyc", ".pyo", ".tmp")


def package_version() -> str:
    """__version__ of addon/nfield/__init__.py, checked against bl_info and blender_manifest.toml."""
    import ast

    tree = ast.parse((PACKAGE_DIR / "__init__.py").read_text())
    version = bl_version = None
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            if node.targets[0].id == "__version__":
                version = ast.literal_eval(node.value)
            elif node.targets[0].id == "bl_info":
                bl_version = ast.literal_eval(node.value).get("version")
    if version is None:
        raise Failure("addon/nfield/__init__.py defines no __version__")
    if bl_version is not None and ".".join(map(str, bl_version)) != version:
        raise Failure(f"bl_info version {bl_version} does not match __version__ {version}")
    manifest = PACKAGE_DIR / "blender_manifest.toml"
    if not manifest.is_file():
        raise Failure(f"{manifest.relative_to(ROOT)} is missing")
    for line in manifest.read_text().splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "version" and value.strip().strip('"') != version:
            raise Failure(f"blender_manifest.toml version {value.strip()} does not match __version__ {version}")
    return version


def bundled_libraries(module: Path) -> list[tuple[str, Path]]:
    """(soname, real file) of every shared library `module` needs that is not a system library (from ldd)."""
    out = run(["ldd", module], capture=True, quiet=True).stdout
    libs = []
    for line in out.splitlines():
        parts = line.strip().split()
        if len(parts) >= 3 and parts[1] == "=>":
            name, path = parts[0], parts[2]
            if path == "not":
                raise Failure(f"{module.name} needs {name}, which is not installed (ldd: not found)")
            if not name.startswith(PACKAGE_SYSTEM_LIBS):
                libs.append((name, Path(path).resolve()))
    return libs


def check_rpath(module: Path) -> None:
    out = run(["readelf", "-d", module], capture=True, quiet=True).stdout
    if "(RPATH)" not in out or "$ORIGIN/libs" not in out:
        raise Failure(f"{module} has no DT_RPATH $ORIGIN/libs (CMakeLists.txt sets it; reconfigure the build)")


def cmd_package(args) -> int:
    """dist/nfield-<version>-linux-x64.zip: nfield/ (package, compiled module, bundled libs/, manifest)."""
    import fcntl

    version = package_version()
    dist = ROOT / "dist"
    dist.mkdir(exist_ok=True)
    # Serialize concurrent `package` runs (e.g. two test sessions): two ninja processes in one build
    # directory corrupt its logs and force full rebuilds.
    with open(dist / ".package.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return _package_locked(args, version, dist)


def _package_locked(args, version: str, dist: Path) -> int:
    import zipfile

    python = getattr(args, "python", None)
    modules = [build(python)] if python else build_all()
    if not modules:
        raise Failure("no interpreter is set up to build the module: run `python3 build_addon.py setup`")
    libs: dict[str, Path] = {}
    for module in modules:
        check_rpath(module)
        for soname, real in bundled_libraries(module):
            if libs.setdefault(soname, real) != real:
                raise Failure(f"{soname} resolves to {libs[soname]} and to {real} for different modules")
    target = dist / f"nfield-{version}-linux-x64.zip"
    tmp = target.with_name(target.name + ".tmp")
    count = 0
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(PACKAGE_DIR.rglob("*")):
            rel = path.relative_to(PACKAGE_DIR)
            if path.is_dir() or any(p in PACKAGE_EXCLUDE_DIRS for p in rel.parts[:-1]):
                continue
            if path.name.endswith(PACKAGE_EXCLUDE_SUFFIXES) or path.name.startswith("_native"):
                continue  # compiled modules: only the ones just built go in (below)
            zf.write(path, f"nfield/{rel.as_posix()}")
            count += 1
        for module in modules:  # one per Python ABI, side by side
            zf.write(module, f"nfield/{module.name}")
        for soname, real in sorted(libs.items()):  # shared by every module: bundled once
            zf.write(real, f"nfield/libs/{soname}")
    os.replace(tmp, target)
    size = target.stat().st_size / 1e6
    say(f"packaged {target.relative_to(ROOT)} ({size:.1f} MB): {count} files, "
        f"{', '.join(m.name for m in modules)}, {len(libs)} bundled libraries ({', '.join(sorted(libs))})")
    return 0


# ---------------------------------------------------------------------------------------- main

def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="build_addon.py", description="nfield build driver")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    sub.add_parser("setup", help="install Debian packages and .venv if missing (idempotent)")
    b = sub.add_parser("build", help="build the native module and copy it into addon/nfield/")
    b.add_argument("--python", metavar="PATH",
                   help="build for this interpreter only (default: every interpreter set up, .venv and .venv-313)")
    b.add_argument("--debug", action="store_true", help="Debug build")
    b.add_argument("--sanitize", action="store_true",
                   help="-fsanitize=address,undefined, separate build dir, not copied into addon/")
    sub.add_parser("test", help="every test leg (--quick: native and core tests only), then `sanitize` and a short `fuzz` run "
                                "(extra arguments go to pytest; NFIELD_SKIP_HARDENING=1 skips the latter two)")
    sub.add_parser("sanitize", help="ASan/UBSan build + the native pytest files under it (extra arguments go to pytest)")
    fz = sub.add_parser("fuzz", help="build the libFuzzer targets (clang++-14) and run each for a bounded time")
    fz.add_argument("targets", nargs="*", metavar="TARGET", help=f"default: all ({', '.join(FUZZ_TARGETS)})")
    fz.add_argument("--seconds", type=int, default=60, metavar="N", help="per target (default 60)")
    sub.add_parser("demo", help="setup + build + run the main CLI job")
    sub.add_parser("bench", help="setup + build + bench/run.py (extra arguments go to it)")
    pk = sub.add_parser("package", help="build the module and write dist/nfield-<version>-linux-x64.zip")
    pk.add_argument("--python", metavar="PATH",
                    help="only a module for this interpreter (default: one per interpreter set up)")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        # test/bench pass every following argument through verbatim.
        if argv and argv[0] == "test":
            return cmd_test(argv[1:])
        if argv and argv[0] == "bench":
            return cmd_bench(argv[1:])
        if argv and argv[0] == "sanitize":
            return cmd_sanitize(argv[1:])
        args = make_parser().parse_args(argv)
        handlers = {"setup": cmd_setup, "build": cmd_build, "demo": cmd_demo, "package": cmd_package,
                    "fuzz": cmd_fuzz}
        return handlers[args.command](args)
    except Failure as exc:
        print(f"build_addon: error: {exc}", file=sys.stderr, flush=True)
        return exc.code
    except KeyboardInterrupt:
        print("build_addon: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
