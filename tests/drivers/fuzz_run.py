"""The fuzz run of `build_addon.py fuzz` (docs/hardening.md): the libFuzzer targets of native/fuzz, built
with clang++-14, each run for a bounded time on its seeds and on what earlier runs found.

Not a test module: build_addon.py imports it (driver()) and passes itself as `driver`, for its run, say,
Failure and build helpers; this file holds only what is particular to fuzzing.
"""
from __future__ import annotations

import shlex
import shutil
import subprocess
import time
from pathlib import Path

FUZZ_SECONDS_IN_TEST = 45
# A single input slower than this is a finding (a hang); memory beyond the limit too.
FUZZ_TIMEOUT_SECONDS = 10
FUZZ_RSS_LIMIT_MB = 2048


def fuzz_targets(driver) -> dict[str, list[str]]:
    """target -> libFuzzer options of its own: the file targets take inputs up to 4 kB (headers plus a few
    dozen elements), the ingestion target decodes at most 24 vertices and 48 faces (< 1 kB)."""
    dicts = driver.ROOT / "native" / "fuzz" / "dict"
    return {
        "parse_obj": ["-max_len=4096", f"-dict={dicts / 'obj.dict'}"],
        "parse_off": ["-max_len=4096", f"-dict={dicts / 'off.dict'}"],
        "parse_ply": ["-max_len=4096", f"-dict={dicts / 'ply.dict'}"],
        "mesh_ingestion": ["-max_len=1024"],
    }


def build_fuzzers(driver) -> Path:
    """Configures (once) and builds native/fuzz with clang++-14 into build/fuzz-clang14."""
    clang = shutil.which("clang++-14")
    if clang is None:
        raise driver.Failure("clang++-14 not found: run `python3 build_addon.py setup` (Debian clang-14, "
                             "libclang-rt-14-dev)")
    build_dir = driver.BUILD_ROOT / "fuzz-clang14"
    driver.cmake_build(build_dir, {"CMAKE_CXX_COMPILER": clang, "CMAKE_BUILD_TYPE": "Debug", "NFIELD_FUZZ": "ON",
                                   "NFIELD_BUILD_PYTHON": "OFF", "NFIELD_BUILD_TESTS": "OFF"},
                       target="nfield_fuzzers")
    return build_dir


def libfuzzer_stats(output: str) -> dict:
    """The stat::name: value lines of -print_final_stats=1."""
    stats = {}
    for line in output.splitlines():
        if line.startswith("stat::"):
            key, _, value = line[len("stat::"):].partition(":")
            stats[key.strip()] = value.strip()
    return stats


def run_fuzz_target(driver, name: str, seconds: int, build_dir: Path) -> tuple[bool, str]:
    """Runs one target for `seconds` on its seeds (native/fuzz/corpus/<name>, always replayed first) plus
    the inputs earlier runs found (build/fuzz/corpus/<name>, where new ones are written). Returns
    (ok, summary line). A finding's input is saved under build/fuzz/findings/<name>/."""
    shown = driver.shown
    binary = build_dir / f"fuzz_{name}"
    seeds = driver.ROOT / "native" / "fuzz" / "corpus" / name
    work_root = driver.BUILD_ROOT / "fuzz"
    work = work_root / "corpus" / name
    findings = work_root / "findings" / name
    work.mkdir(parents=True, exist_ok=True)
    findings.mkdir(parents=True, exist_ok=True)
    log = work_root / f"{name}.log"
    cmd = [binary, f"-max_total_time={seconds}", f"-timeout={FUZZ_TIMEOUT_SECONDS}",
           f"-rss_limit_mb={FUZZ_RSS_LIMIT_MB}", "-print_final_stats=1", f"-artifact_prefix={findings}/",
           *fuzz_targets(driver)[name], work, seeds]
    print("+ " + " ".join(shlex.quote(shown(str(c))) for c in cmd) + f"  > {shown(str(log))}", flush=True)
    with open(log, "w") as out:
        proc = subprocess.run([str(c) for c in cmd], stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
    output = log.read_text(errors="replace")
    stats = libfuzzer_stats(output)
    runs, speed = stats.get("number_of_executed_units", "?"), stats.get("average_exec_per_sec", "?")
    summary = f"{name}: {runs} runs, {speed} exec/s, exit {proc.returncode}"
    if proc.returncode == 0:
        return True, summary
    # Show the report (libFuzzer prints the sanitizer report and the artifact path) and how to replay it.
    print("\n".join(output.splitlines()[-60:]), flush=True)
    artifacts = sorted(findings.glob("*"), key=lambda p: p.stat().st_mtime)
    if artifacts:
        driver.say(f"{name}: finding saved as {shown(str(artifacts[-1]))}; reproduce with:\n"
                   f"    {shown(str(binary))} {shown(str(artifacts[-1]))}")
    return False, summary + f" FINDING (log {shown(str(log))})"


def run_fuzz_job(driver, seconds: int, targets: list[str]) -> int:
    """Builds the fuzzers and runs the chosen targets one after the other; fails if any found something."""
    known = fuzz_targets(driver)
    names = targets or list(known)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise driver.Failure(f"unknown fuzz target(s) {', '.join(unknown)}; targets: {', '.join(known)}")
    if seconds < 1:
        raise driver.Failure("--seconds must be at least 1")
    start = time.monotonic()
    build_dir = build_fuzzers(driver)
    built = time.monotonic()
    results = [run_fuzz_target(driver, name, seconds, build_dir) for name in names]
    driver.say(f"fuzz job: build {built - start:.0f} s, fuzzing {time.monotonic() - built:.0f} s")
    for ok, line in results:
        driver.say(("  ok       " if ok else "  FAILED   ") + line)
    failed = [line for ok, line in results if not ok]
    if failed:
        raise driver.Failure(f"{len(failed)} fuzz target(s) found a problem (see above)")
    return 0
