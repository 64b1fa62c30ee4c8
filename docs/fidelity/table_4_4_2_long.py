"""Four cells of Table 4.4.2 (X = 0) run for 30 s: does a decaying cell grow back?

Usage: .venv/bin/python docs/fidelity/table_4_4_2_long.py
Writes docs/fidelity/table_4_4_2_long.json (RMS radial amplitude at node 1 per 0.25 s window).
"""
import importlib.util
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location('table_4_4_2', HERE / 'table_4_4_2.py')
t = importlib.util.module_from_spec(spec)
spec.loader.exec_module(t)

CELLS = [(1.081, 25.0, 1.0), (1.081, 25.0, 3.0), (1.081, 5.0, 1.0), (1.047, 15.0, 3.0)]


def main(duration=30.0):
    k_on = t.onset('hpotp', t.KCC_KEY, t.BASE, start_hi=1e5)['onset_kcc_N_m']
    out = []
    for ratio, w, d in CELLS:
        cell = t.run_cell(ratio * k_on, w, d, duration, multiplier=0.0)
        cell.update(ratio=ratio, weight_lb=w, gap_mil=d, duration_s=duration,
                    bare_rate_1_s=t.bare_growth(ratio * k_on, w)[0])
        out.append(cell)
        print(json.dumps({k: v for k, v in cell.items() if k != 'rms'}), flush=True)
    (HERE / 'table_4_4_2_long.json').write_text(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
