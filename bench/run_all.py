"""Run every benchmark in bench/ and write one JSON summary.

Each benchmark is a script that prints one JSON object on stdout (on one line or indented; a
script that logs lines before it prints it on the last line). Usage:
    .venv/bin/python bench/run_all.py [--out out/bench.json] [--only NAME ...]
"""
import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def read_result(stdout: str) -> dict | None:
    """The JSON object a benchmark printed: its whole stdout (indented JSON spans lines), else its last
    line (lines logged before it); None if neither is one."""
    text = stdout.strip()
    for candidate in (text, text.splitlines()[-1] if text else ''):
        try:
            result = json.loads(candidate)
        except json.JSONDecodeError:
            continue
        if isinstance(result, dict):
            return result
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', default='out/bench.json', help='summary file (default out/bench.json)')
    ap.add_argument('--only', nargs='*', help='benchmark names (file stems) to run; default all')
    args = ap.parse_args()
    scripts = sorted(p for p in HERE.glob('*.py') if p.name != Path(__file__).name)
    if args.only:
        scripts = [p for p in scripts if p.stem in args.only]
    summary, failed = {'python': sys.version.split()[0], 'started': time.strftime('%Y-%m-%dT%H:%M:%S')}, []
    for script in scripts:
        print(f'[bench] {script.stem} ...', file=sys.stderr, flush=True)
        t0 = time.monotonic()
        r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True)
        result = read_result(r.stdout)
        if result is None:
            result = {'error': (r.stderr.strip().splitlines() or ['no output'])[-1]}
        if r.returncode != 0:
            failed.append(script.stem)
            result.setdefault('error', f'exit status {r.returncode}')
        result['wall_s'] = round(time.monotonic() - t0, 2)
        summary[script.stem] = result
        print(json.dumps({script.stem: result}), flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=2) + '\n')
    print(f'[bench] wrote {out}', file=sys.stderr)
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
