"""Fuzz softpipe's OBJ and scene-file parsers for a bounded time.

    python fuzz/run.py --seconds 60                 # each target for 60 s, one after the other
    python fuzz/run.py --seconds 300 --parallel     # both targets at once (one core each)
    python fuzz/run.py --targets scene --merge      # and keep the inputs that found new coverage
    python fuzz/run.py --engine hypothesis          # without atheris

Engines: ``atheris`` (coverage-guided libFuzzer; ``pip install atheris``) is used when
it imports, else ``hypothesis`` (random mutations of the corpus with the dictionary's
tokens; not coverage-guided). Both check the contract of targets.py on every input and
bound the time per input (``--timeout``, default 10 s): longer is a hang, and a finding.

Work files go to ``out/fuzz/``: ``work/TARGET`` (inputs the fuzzer kept) and
``findings/`` (the input of each finding, e.g. ``obj-crash-<sha1>``). ``--merge``
adds the kept inputs that reach new coverage to ``fuzz/corpus/TARGET`` (atheris only).
Exit status: 0 no finding, 1 findings, 2 bad usage.
"""
from __future__ import annotations

import argparse
import hashlib
import re
import subprocess
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT = ROOT / "out" / "fuzz"
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))

import targets  # noqa: E402


def have_atheris() -> bool:
    try:
        import atheris  # noqa: F401
    except ImportError:
        return False
    return True


def atheris_command(target: str, seconds: float, timeout: float, extra=()):
    work = OUT / "work" / target
    findings = OUT / "findings"
    work.mkdir(parents=True, exist_ok=True)
    findings.mkdir(parents=True, exist_ok=True)
    return [sys.executable, str(HERE / "fuzz_atheris.py"), target,
            f"-max_total_time={max(int(seconds), 1)}", f"-timeout={max(int(timeout), 1)}",
            "-rss_limit_mb=4096", "-max_len=16384", f"-dict={HERE / (target + '.dict')}",
            f"-artifact_prefix={findings}/{target}-", "-print_final_stats=1", *extra,
            str(work), str(targets.CORPUS / target)]


def summarize_atheris(target: str, code: int, log: str, seconds: float) -> dict:
    stats = dict(re.findall(r"stat::(\w+):\s*(\d+)", log))
    cov = re.findall(r"cov: (\d+) ft: (\d+) corp: (\d+)", log)
    artifacts = re.findall(r"Test unit written to (\S+)", log)
    summary = {"target": target, "engine": "atheris", "seconds": round(seconds, 1), "exit": code,
               "runs": int(stats.get("number_of_executed_units", 0)),
               "coverage": cov[-1][0] if cov else "?", "features": cov[-1][1] if cov else "?",
               "corpus": cov[-1][2] if cov else "?", "findings": artifacts}
    if code != 0 and not artifacts:
        summary["findings"] = [f"(exit status {code}; see the log)"]
    return summary


def run_atheris(names, seconds: float, timeout: float, parallel: bool, merge: bool):
    logs_dir = OUT / "logs"
    logs_dir.mkdir(parents=True, exist_ok=True)
    procs = []
    results = []
    for name in names:
        log_path = logs_dir / f"{name}.log"
        log = open(log_path, "w")
        print(f"fuzz {name}: atheris for {seconds:.0f} s (log: {log_path})", flush=True)
        start = time.monotonic()
        p = subprocess.Popen(atheris_command(name, seconds, timeout), stdout=log, stderr=subprocess.STDOUT,
                             cwd=ROOT)
        procs.append((name, p, log, log_path, start))
        if not parallel:
            results.append(_finish(*procs.pop()))
    results.extend(_finish(*item) for item in procs)
    if merge:
        for name in names:
            before = len(targets.corpus_files(name))
            subprocess.run([sys.executable, str(HERE / "fuzz_atheris.py"), name, "-merge=1",
                            f"-timeout={max(int(timeout), 1)}", "-max_len=16384", str(targets.CORPUS / name),
                            str(OUT / "work" / name)], cwd=ROOT, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, check=False)
            print(f"fuzz {name}: merged: corpus {before} → {len(targets.corpus_files(name))} files")
    return results


def _finish(name, p, log, log_path, start):
    code = p.wait()
    log.close()
    return summarize_atheris(name, code, log_path.read_text(errors="replace"), time.monotonic() - start)


# ---------------------------------------------------------------------------- the hypothesis engine


def dictionary_tokens(target: str):
    tokens = []
    for line in (HERE / f"{target}.dict").read_text().splitlines():
        line = line.strip()
        if line.startswith('"') and line.endswith('"'):
            tokens.append(line[1:-1].encode("latin-1").decode("unicode_escape").encode("utf-8"))
    return tokens


def run_hypothesis(names, seconds: float, timeout: float):
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import strategies as st

    results = []
    for name in names:
        check = targets.CHECKS[name]
        seeds = [p.read_bytes() for p in targets.corpus_files(name)]
        tokens = dictionary_tokens(name)
        print(f"fuzz {name}: hypothesis for {seconds:.0f} s ({len(seeds)} seeds, {len(tokens)} tokens)", flush=True)

        @st.composite
        def inputs(draw):
            data = bytearray(draw(st.sampled_from(seeds)) if draw(st.integers(0, 9)) else
                             draw(st.binary(max_size=512)))
            for _ in range(draw(st.integers(0, 8))):
                op = draw(st.integers(0, 4))
                pos = draw(st.integers(0, len(data)))
                if op == 0:
                    data[pos:pos] = draw(st.sampled_from(tokens))
                elif op == 1:
                    data[pos:pos + draw(st.integers(1, 16))] = b""
                elif op == 2:
                    data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
                elif op == 3 and data:  # duplicate a slice
                    end = draw(st.integers(pos, min(len(data), pos + 200)))
                    data[pos:pos] = data[pos:end] * draw(st.integers(1, 50))
                elif op == 4:  # a number in a new form
                    data[pos:pos] = draw(st.sampled_from([b"-1", b"0", b"1e309", b"nan", b"99999999999999999999",
                                                          b"-0", b"4294967296", b"1_000", b"0x10"]))
            return bytes(data)

        failures = []
        runs = [0]

        @settings(max_examples=500, deadline=None, database=None, derandomize=False,
                  suppress_health_check=list(HealthCheck), phases=[Phase.generate, Phase.shrink])
        @given(inputs())
        def fuzz_one(data):
            runs[0] += 1
            try:
                targets.run_with_time_limit(check, data, timeout)
            except BaseException:
                failures.append(data)
                raise

        start = time.monotonic()
        findings = []
        while time.monotonic() - start < seconds:
            failures.clear()
            try:
                fuzz_one()
            except Exception as e:
                data = failures[-1] if failures else b""
                path = OUT / "findings" / f"{name}-crash-{hashlib.sha1(data).hexdigest()}"
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
                findings.append(str(path))
                print(f"fuzz {name}: FINDING {type(e).__name__}: {str(e)[:200]} → {path}", flush=True)
                traceback.print_exception(e, limit=-3)
        results.append({"target": name, "engine": "hypothesis", "seconds": round(time.monotonic() - start, 1),
                        "exit": 1 if findings else 0, "runs": runs[0], "findings": findings})
    return results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--seconds", type=float, default=60.0, help="time per target (default 60)")
    ap.add_argument("--targets", default="obj,scene", help="comma-separated: obj, scene (default both)")
    ap.add_argument("--engine", choices=("auto", "atheris", "hypothesis"), default="auto")
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds one input may take (default 10)")
    ap.add_argument("--parallel", action="store_true", help="run the targets at the same time (atheris)")
    ap.add_argument("--merge", action="store_true", help="add new-coverage inputs to fuzz/corpus (atheris)")
    args = ap.parse_args(argv)
    names = [t.strip() for t in args.targets.split(",") if t.strip()]
    unknown = [t for t in names if t not in targets.TARGETS]
    if unknown or not names:
        ap.error(f"unknown target(s) {unknown}; expected {', '.join(targets.TARGETS)}")
    engine = args.engine
    if engine == "auto":
        engine = "atheris" if have_atheris() else "hypothesis"
        if engine == "hypothesis":
            print("fuzz: atheris is not installed (pip install atheris); using hypothesis", flush=True)
    if engine == "atheris":
        if not have_atheris():
            ap.error("atheris is not installed: pip install atheris")
        results = run_atheris(names, args.seconds, args.timeout, args.parallel, args.merge)
    else:
        results = run_hypothesis(names, args.seconds, args.timeout)
    bad = False
    for r in results:
        extra = (f", coverage {r['coverage']}, features {r['features']}, corpus {r['corpus']}"
                 if "coverage" in r else "")
        state = "no findings" if not r["findings"] else f"FINDINGS: {', '.join(r['findings'])}"
        print(f"fuzz {r['target']}: {r['engine']}, {r['seconds']} s, {r['runs']} inputs{extra}: {state}")
        bad |= bool(r["findings"])
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
