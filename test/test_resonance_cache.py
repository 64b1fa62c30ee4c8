"""The resonance designs' cache on disk (``live/resonance_design.py``, ``_cache_dir.py``).

A design read back must be the fitted one bit for bit; a damaged, unreadable or unwritable
cache costs a fit, never an error or a message above debug level. Every test points the
cache into ``tmp_path`` (``IMPACT_DAMPER_SIM_DESIGN_CACHE``), so the user's own is never
touched.
"""
import errno
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from impact_damper_sim import _cache_dir
from impact_damper_sim.live import resonance_design as rd

# (fn, q, band, lowpass) in units of the step rate, as _design takes them
HPOTP = (5.0, 25.0, 0.08, 0.08)          # hpotp's sensor: fn 50 kHz at 10 kHz, 800 Hz: 1 biquad
IDENTITY = (100.0, 25.0, 0.08, 0.08)     # fn 1 MHz: the lift is below the floor, no section
TWO_SECTIONS = (1.75, 25.0, 0.25, 0.25)  # fn 35 kHz at 20 kHz, 5 kHz: 2 biquads
#: The fit itself, uncached and uncounted: the reference a cached design must equal
FIT = rd._fit_design


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """The designs' cache directory, in ``tmp_path``, and an empty in-process cache."""
    directory = tmp_path / 'designs'
    monkeypatch.setenv(_cache_dir.DESIGN_CACHE_ENV, str(directory))
    rd._design.cache_clear()
    yield directory
    rd._design.cache_clear()


#: Each input's fit, made once for the module (0.2-0.6 s each; the fit is a pure function,
#: so its result is the same bit for bit every time: test_a_cached_design_is_the_fitted_one)
_FITTED = {}


@pytest.fixture
def fits(monkeypatch):
    """The arguments of every fit :func:`rd._design` runs, in order; each returns a copy of
    the input's fit (made once for the module)."""
    calls = []
    fit = rd._fit_design

    def counted(*args):
        calls.append(args)
        if args not in _FITTED:
            _FITTED[args] = fit(*args)
        sos, checked = _FITTED[args]
        return (None if sos is None else sos.copy()), tuple(checked)

    monkeypatch.setattr(rd, '_fit_design', counted)
    return calls


def refuse_to_fit(monkeypatch):
    """Make any further fit fail the test: what follows must come from the disk cache."""
    def refit(*args):
        raise AssertionError(f'fitted {args} again instead of reading the cache')
    monkeypatch.setattr(rd, '_fit_design', refit)


def from_disk(args, monkeypatch):
    """The design of ``args`` as a new process gets it: the in-process cache emptied."""
    rd._design.cache_clear()
    with monkeypatch.context() as m:
        refuse_to_fit(m)
        return rd._design(*args)


def assert_identical(got, expected):
    """The same design bit for bit: sections (values, dtype, shape) and checked floats."""
    (sos, checked), (sos_expected, checked_expected) = got, expected
    if sos_expected is None:
        assert sos is None
    else:
        assert sos.dtype == sos_expected.dtype == np.float64
        assert sos.shape == sos_expected.shape
        assert np.array_equal(sos, sos_expected, equal_nan=True)
        assert sos.tobytes() == sos_expected.tobytes()      # -0.0 and nan bits too
    assert all(type(v) is float for v in checked)
    assert [v.hex() for v in checked] == [v.hex() for v in checked_expected]


def entries(directory):
    return sorted(p.name for p in Path(directory).iterdir()) if directory.exists() else []


@pytest.mark.parametrize('args', [HPOTP, IDENTITY, TWO_SECTIONS],
                         ids=['hpotp', 'identity', 'two-sections'])
def test_a_cached_design_is_the_fitted_one_bit_for_bit(cache, fits, monkeypatch, args):
    fresh = FIT(*args)
    first = rd._design(*args)
    assert len(fits) == 1 and len(entries(cache)) == 1
    assert_identical(first, fresh)
    assert_identical(from_disk(args, monkeypatch), fresh)


def test_what_design_resonance_returns_from_the_cache_is_the_fitted_design(cache,
                                                                           monkeypatch):
    fitted = rd.design_resonance(50e3, 25.0, 10e3, 800.0)
    rd._design.cache_clear()
    refuse_to_fit(monkeypatch)
    cached = rd.design_resonance(50e3, 25.0, 10e3, 800.0)
    assert cached.sos.tobytes() == fitted.sos.tobytes() and cached.sos.shape == (1, 6)
    for field in ('band_hz', 'gain_error', 'phase_error_deg', 'lift_error',
                  'gain_above_band', 'error_above_band', 'pole_radius'):
        assert getattr(cached, field).hex() == getattr(fitted, field).hex(), field


def test_a_refused_design_and_awkward_floats_round_trip(cache, monkeypatch):
    """None (refused), a score of inf, -0.0, nan and a subnormal come back as they went."""
    awkward_sos = np.array([[-0.0, 5e-324, np.nextafter(1.0, 2.0), 1.0, np.nan, -1e300]])
    designs = {(1.5, 25.0, 0.4, 0.4): (None, (np.inf, 0.0113, 1.7, 0.2, 1.0, 0.01, 0.99)),
               (1.6, 25.0, 0.4, 0.4): (awkward_sos, (-0.0, 5e-324, np.nan, 0.1, 0.2, 0.3, 0.4))}
    monkeypatch.setattr(rd, '_fit_design', lambda *args: designs[args])
    for args, designed in designs.items():
        assert_identical(rd._design(*args), designed)
        assert_identical(from_disk(args, monkeypatch), designed)
    rd._design.cache_clear()
    refuse_to_fit(monkeypatch)
    with pytest.raises(ValueError, match='cannot be realised causally'):
        rd.design_resonance(15e3, 25.0, 10e3, 4e3)     # (1.5, 25, 0.4, 0.4), read back


CORRUPT = {
    'empty': b'',
    'truncated': b'{"key": {"format": 1, "inputs": ["0x1.4',
    'not utf-8': b'\xff\xfe\x00garbage',
    'json null': b'null',
    'json list': b'[1, 2, 3]',
}


def damaged(entry, how):
    """A readable JSON entry made unusable in one way."""
    entry = json.loads(json.dumps(entry))
    if how == 'another key':            # e.g. a name collision: must not be taken
        entry['key']['inputs'][0] = (6.0).hex()
    elif how == 'six checked values':
        entry['checked'] = entry['checked'][:6]
    elif how == 'checked as a string':      # 7 characters: 7 hex digits if taken
        entry['checked'] = '1234567'
    elif how == 'values as a string':
        entry['sos']['values'] = 'abcdef'
    elif how == 'a value short':
        entry['sos']['values'] = entry['sos']['values'][:-1]
    elif how == 'four sections':            # more than RESONANCE_MAX_SECTIONS
        entry['sos'] = {'shape': [4, 6], 'values': entry['sos']['values'] * 4}
    elif how == 'seven columns':
        entry['sos']['shape'] = [1, 7]
    elif how == 'not hex':
        entry['sos']['values'][0] = 0.5
    return json.dumps(entry).encode()


@pytest.mark.parametrize('how', [*CORRUPT, 'another key', 'six checked values',
                                 'checked as a string', 'values as a string',
                                 'a value short', 'four sections', 'seven columns', 'not hex'])
def test_a_corrupt_entry_is_fitted_again_and_rewritten(cache, fits, monkeypatch, caplog,
                                                       capfd, how):
    fresh = rd._design(*HPOTP)
    (path,) = cache.iterdir()
    good = json.loads(path.read_text())
    path.write_bytes(CORRUPT[how] if how in CORRUPT else damaged(good, how))
    rd._design.cache_clear()
    fits.clear()
    caplog.set_level(logging.DEBUG, logger=rd.__name__)
    assert_identical(rd._design(*HPOTP), fresh)
    assert fits == [HPOTP]
    assert json.loads(path.read_text()) == good            # rewritten whole
    assert_identical(from_disk(HPOTP, monkeypatch), fresh)
    assert [r.levelno for r in caplog.records] == [logging.DEBUG]   # a note, no noise
    assert capfd.readouterr() == ('', '')


def test_an_entry_that_cannot_be_read_costs_a_fit(cache, fits, caplog, capfd):
    """The entry's path is a directory: neither read nor replaced, and the design stands."""
    fresh = rd._design(*HPOTP)
    (path,) = cache.iterdir()
    path.unlink()
    path.mkdir()
    rd._design.cache_clear()
    caplog.set_level(logging.DEBUG, logger=rd.__name__)
    assert_identical(rd._design(*HPOTP), fresh)
    assert len(fits) == 2 and path.is_dir()
    assert [p.name for p in cache.iterdir()] == [path.name]          # no temporary left
    assert {r.levelno for r in caplog.records} == {logging.DEBUG}
    assert capfd.readouterr() == ('', '')


def test_a_directory_that_cannot_be_made_still_gives_the_design(tmp_path, monkeypatch, fits,
                                                                caplog, capfd):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    monkeypatch.setenv(_cache_dir.DESIGN_CACHE_ENV, str(blocker / 'designs'))
    rd._design.cache_clear()
    caplog.set_level(logging.DEBUG, logger=rd.__name__)
    try:
        designed = rd._design(*HPOTP)
    finally:
        rd._design.cache_clear()
    assert_identical(designed, FIT(*HPOTP))
    assert fits == [HPOTP]
    assert sorted(p.name for p in tmp_path.iterdir()) == ['a_file']
    assert {r.levelno for r in caplog.records} == {logging.DEBUG}
    assert capfd.readouterr() == ('', '')


@pytest.mark.parametrize('failure', [errno.EROFS, errno.EACCES, errno.ENOSPC],
                         ids=['read-only', 'no-permission', 'disk-full'])
def test_a_read_only_or_full_cache_still_gives_the_design(cache, fits, monkeypatch, caplog,
                                                          capfd, failure):
    """Root writes into a chmod-ed directory, so the file system's refusals are simulated:
    creating the temporary file (read-only, no permission), or writing it (disk full, half
    written)."""
    real_dump = json.dump
    cache.mkdir()

    def fail_to_create(*args, **kwargs):
        raise OSError(failure, os.strerror(failure))

    def half_written(obj, f, **kwargs):
        f.write(json.dumps(obj)[:40])
        f.flush()
        raise OSError(failure, os.strerror(failure))

    if failure == errno.ENOSPC:
        monkeypatch.setattr(rd.json, 'dump', half_written)
    else:
        monkeypatch.setattr(rd.tempfile, 'mkstemp', fail_to_create)
    caplog.set_level(logging.DEBUG, logger=rd.__name__)
    designed = rd._design(*HPOTP)
    monkeypatch.setattr(rd.json, 'dump', real_dump)
    assert_identical(designed, FIT(*HPOTP))
    assert fits == [HPOTP]
    assert entries(cache) == []                          # no entry, no temporary left
    assert {r.levelno for r in caplog.records} == {logging.DEBUG}
    assert capfd.readouterr() == ('', '')


def test_a_read_only_cache_is_still_read(cache, monkeypatch):
    fresh = rd._design(*HPOTP)

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(rd.tempfile, 'mkstemp', read_only)
    assert_identical(from_disk(HPOTP, monkeypatch), fresh)


def test_an_entry_appears_whole_or_not_at_all(cache, monkeypatch):
    """Written into a temporary file of the same directory, complete, then renamed over the
    entry's name: a process starting meanwhile reads all of it or nothing."""
    real_replace = os.replace
    replaced = []

    def checked_replace(src, dst):
        src, dst = Path(src), Path(dst)
        assert src.parent == dst.parent == cache         # same file system: an atomic rename
        assert not dst.exists()                          # nothing written under the name yet
        json.loads(src.read_text())                      # the temporary is complete
        replaced.append(dst)
        real_replace(src, dst)

    monkeypatch.setattr(rd.os, 'replace', checked_replace)
    rd._design(*HPOTP)
    assert replaced == list(cache.iterdir())


@pytest.mark.parametrize('change', ['source', 'numpy', 'inputs by one ulp'])
def test_a_change_of_the_key_misses(cache, fits, monkeypatch, change):
    rd._design(*HPOTP)
    rd._design.cache_clear()
    args = HPOTP
    if change == 'source':
        monkeypatch.setattr(rd, '_SOURCE_DIGEST', 'f' * 64)
        monkeypatch.setattr(rd, '_source_digest', lambda: 'f' * 64)
    elif change == 'numpy':
        monkeypatch.setattr(rd.np, '__version__', '0.0.0')
    else:
        args = (np.nextafter(HPOTP[0], np.inf), *HPOTP[1:])
    rd._design(*args)
    assert fits == [HPOTP, args]
    assert len(entries(cache)) == 2


def test_a_source_edited_since_the_import_neither_reads_nor_writes(cache, fits, monkeypatch):
    """The running code is not the file's any more: its designs must not be stored under the
    new file's digest, nor the new file's entries taken."""
    rd._design(*HPOTP)
    monkeypatch.setattr(rd, '_source_digest', lambda: 'e' * 64)
    rd._design.cache_clear()
    rd._design(*HPOTP)
    rd._design(*IDENTITY)
    assert fits == [HPOTP, HPOTP, IDENTITY]
    assert len(entries(cache)) == 1


CHILD = '''
import json, sys
from impact_damper_sim.live import resonance_design as rd
if sys.argv[1] == 'second':
    def refit(*args):
        raise AssertionError('the second process fitted again')
    rd._fit_design = refit
d = rd.design_resonance(50e3, 25.0, 10e3, 800.0)
print(json.dumps({'sos': [v.hex() for v in d.sos.ravel().tolist()], 'shape': d.sos.shape,
                  'errors': [d.gain_error.hex(), d.phase_error_deg.hex(), d.pole_radius.hex()]}))
'''


def test_a_second_process_reads_the_first_ones_design(tmp_path):
    env = dict(os.environ, **{_cache_dir.DESIGN_CACHE_ENV: str(tmp_path / 'designs')})

    def run(which):
        done = subprocess.run([sys.executable, '-c', CHILD, which], env=env,
                              capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert done.returncode == 0, done.stderr[-3000:]
        assert done.stderr == ''                          # no noise at the start
        return json.loads(done.stdout)

    first = run('first')
    assert len(entries(tmp_path / 'designs')) == 1
    assert run('second') == first
    assert first['shape'] == [1, 6]


def test_the_cache_can_be_switched_off(tmp_path, monkeypatch, fits):
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'xdg'))
    for value in _cache_dir.DESIGN_CACHE_OFF + ('OFF',):
        monkeypatch.setenv(_cache_dir.DESIGN_CACHE_ENV, value)
        assert _cache_dir.design_cache_dir() is None
    rd._design.cache_clear()
    try:
        rd._design(*IDENTITY)
    finally:
        rd._design.cache_clear()
    assert fits == [IDENTITY]
    assert list(tmp_path.iterdir()) == []


def test_the_design_cache_lives_beside_numba_s_and_follows_xdg(tmp_path, monkeypatch):
    monkeypatch.delenv(_cache_dir.DESIGN_CACHE_ENV, raising=False)
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'cache'))
    root = tmp_path / 'cache' / 'impact_damper_sim'
    assert _cache_dir.cache_root() == root
    assert _cache_dir.design_cache_dir() == root / 'designs'
    assert _cache_dir.default_cache_dir() == root / 'numba'
    home_cache = Path.home() / '.cache' / 'impact_damper_sim'
    for unusable in ('', 'relative/cache'):   # the XDG specification ignores both
        monkeypatch.setenv('XDG_CACHE_HOME', unusable)
        assert _cache_dir.design_cache_dir() == home_cache / 'designs'
    monkeypatch.setenv(_cache_dir.DESIGN_CACHE_ENV, str(tmp_path / 'elsewhere'))
    assert _cache_dir.design_cache_dir() == tmp_path / 'elsewhere'
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(_cache_dir.DESIGN_CACHE_ENV, 'relative')
    assert _cache_dir.design_cache_dir() == tmp_path / 'relative'
    monkeypatch.setenv(_cache_dir.DESIGN_CACHE_ENV, '~/designs')
    assert _cache_dir.design_cache_dir() == Path.home() / 'designs'
