"""The DAQ decimator's reference: ``StreamingDecimator.apply`` as it was before its kept
buffers, a fresh concatenation and a sliding-window view per chunk (issue 39). The tests of
the decimator compare its output with this one bit for bit."""
import numpy as np


def decimate_reference(dec, chunks):
    """``[(index, output)]`` per chunk, as ``dec.apply`` gave them, for a fresh ``dec``."""
    taps = dec.taps
    n = len(taps)
    kernel = taps[::-1].copy()
    history = np.zeros((dec.n_channels, n - 1))
    consumed = 0
    out = []
    for x in chunks:
        buf = np.concatenate([history, x.T], axis=1)
        start = consumed - history.shape[1]
        consumed += len(x)
        history = buf[:, buf.shape[1] - history.shape[1]:]
        last = consumed - 1 - dec.delay
        first = max(0, -(-(consumed - len(x) - dec.delay) // dec.factor) * dec.factor)
        index = np.arange(first, last + 1, dec.factor, dtype=np.int64)
        if index.size == 0:
            out.append((index, np.empty((0, dec.n_channels))))
            continue
        lo = index + dec.delay - (n - 1) - start
        windows = np.lib.stride_tricks.sliding_window_view(buf, n, axis=1)[:, lo]
        out.append((index, (windows @ kernel).T))
    return out
