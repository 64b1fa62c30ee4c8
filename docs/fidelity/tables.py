"""Print the Markdown tables of docs/fidelity.md from the recorded JSON outputs.

Usage: python3 docs/fidelity/tables.py {capture,grid,t442}
"""
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def capture():
    d = json.loads((HERE / 'capture_times.json').read_text())
    print('| method | capture period per start k = 0..11 | captured |')
    print('|---|---|---|')
    for label, r in d['runs'].items():
        caps = r['capture_periods']
        cells = ' '.join('-' if c is None else str(c) for c in caps)
        print(f"| {label} | {cells} | {sum(c is not None for c in caps)} of {len(caps)} |")


def grid():
    rows = json.loads((HERE / 'attractor_grid.json').read_text())['rows']
    names = ['exact', 'exact/none', 'newmark', 'siconos mj']
    print('| r | zeta | mu | e | d | orbit (mm) | rho | ' + ' | '.join(names) + ' |')
    print('|' + '---|' * (7 + len(names)))
    for row in rows:
        r, z, mu, e, dd = row['point']
        cells = []
        for n in names:
            m = row['methods'].get(n)
            if m is None:
                cells.append('')
            elif m['state'] == 'orbit':
                cells.append(f"orbit @{m['capture_period']}")
            elif m['state'] == 'no_impacts':
                cells.append('no impacts')
            elif m['state'] == 'failed':
                cells.append('failed')
            else:
                cells.append(f"other {m['late_min']:.3g}..{m['late_max']:.3g}")
        print(f"| {r} | {z} | {mu} | {e} | {dd:g} | {1e3 * row['orbit_amplitude']:.4f} | "
              f"{row['spectral_radius']:.3f} | " + ' | '.join(cells) + ' |')


def t442():
    d = json.loads((HERE / 'table_4_4_2_X0.json').read_text())
    print('| Kcc/onset | W (lb) | D (mil) | paper | sigma0 (1/s) | late rate (1/s) | '
          'RMS last 0.25 s (mil) | first-half max RMS (mil) | ratio | impacts/s | ours |')
    print('|' + '---|' * 11)
    for c in d['cells']:
        ratio = c['rms_last_mil'] / c['first_half_max_mil']
        ours = 'limit cycle' if ratio > 0.3 else 'decays'
        print(f"| {c['ratio']} | {c['weight_lb']:g} | {c['gap_mil']:g} | {c['paper'][0]} | "
              f"{c['bare_rate_1_s']:.3f} | {c['late_rate_1_s']:+.3f} | {c['rms_last_mil']:.3f} | "
              f"{c['first_half_max_mil']:.3f} | {ratio:.2f} | {c['impacts_per_s']:.0f} | "
              f"{ours} |")


if __name__ == '__main__':
    {'capture': capture, 'grid': grid, 't442': t442}[sys.argv[1]]()
