"""The identifier's learned state on disk: nothing learned is ever lost (issue 10).

* `write_state(path, state)`: atomic (a temporary file in the same directory, flushed and
  fsynced, then `os.replace`): a crash mid-write leaves the old file intact.
* `read_state(path)`: the JSON dict (ValueError with the reason if it is not one).
* `StateFile(path)`: the protocol a node follows, two calls:

      sf = StateFile(path)
      model = sf.load(ident)     # at start: None if absent or rejected (sf.message says why)
      written = sf.save(ident)   # at shutdown: the path written (None if nothing to write)

  A file that cannot be loaded (unreadable, truncated, another version or grid, not finite,
  not an information matrix, or giving a model outside the envelope) is REJECTED: it is
  never overwritten; the new state goes beside it (``<stem>.<n>.json``, the first free n).
  `save` also refuses to write a state that a fresh identifier would reject (it would be
  lost at the next start), and then keeps the previous file too.
  Attributes: `path` (as given), `save_path` (where `save` writes), `loaded` (bool),
  `rejected` (the reason a file was rejected, or None), `message` (one line for the log).
"""
from __future__ import annotations

import json
import os
import pathlib
import tempfile
from typing import Optional


def write_state(path: str, state: dict) -> None:
    """Write `state` as JSON to `path` atomically (temp file in the same directory + rename).
    ValueError if the state is not JSON-able or holds non-finite numbers."""
    try:
        text = json.dumps(state, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'state is not finite JSON: {exc}') from None
    target = pathlib.Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f'.{target.name}.', suffix='.tmp',
                               dir=str(target.parent or '.'))
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def read_state(path: str) -> dict:
    """The JSON object in `path`. ValueError naming the path if it is not a JSON object;
    OSError if it cannot be read."""
    with open(path, encoding='utf-8') as fh:
        try:
            state = json.load(fh)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f'path {path!r} is not a JSON state file: {exc}') from None
    if not isinstance(state, dict):
        raise ValueError(f'path {path!r} holds a JSON {type(state).__name__}, not a state')
    return state


def beside(path: str) -> str:
    """The first free ``<stem>.<n><suffix>`` next to `path` (n = 1, 2, ...)."""
    p = pathlib.Path(path)
    suffix = p.suffix or '.json'
    for n in range(1, 100_000):
        cand = p.with_name(f'{p.stem}.{n}{suffix}')
        if not cand.exists():
            return str(cand)
    raise OSError(f'no free file name beside {path!r}')


class StateFile:
    """Load-at-start / save-at-shutdown of an identifier's state (see module doc)."""

    def __init__(self, path: str):
        if not isinstance(path, str) or not path:
            raise ValueError(f'path must be a non-empty string, got {path!r}')
        self.path = path
        self.save_path = path
        self.loaded = False
        self.rejected: Optional[str] = None
        self.message = ''

    def load(self, ident):
        """Continue `ident` from the file if it exists and is accepted; returns the model
        (or None). Never raises for a bad file: it is kept and `save_path` moves beside it."""
        if not os.path.exists(self.path):
            self.message = f'no state file {self.path} yet: starting empty'
            return None
        try:
            model = ident.set_state(read_state(self.path))
        except (OSError, ValueError) as exc:
            self.rejected = str(exc)
            self.save_path = beside(self.path)
            self.message = (f'state file {self.path} rejected ({exc}); it is kept, the new '
                            f'state will be written to {self.save_path}')
            return None
        self.loaded = True
        self.message = f'continuing from {self.path} ({ident.n_moving} samples of motion)'
        return model

    def save(self, ident) -> Optional[str]:
        """Write `ident`'s state to `save_path` (atomically); returns the path written.
        A state that would be rejected at the next start is written beside instead (the
        previous file is kept); ValueError if it cannot be written at all (not finite)."""
        state = ident.get_state()
        target = self.save_path
        problem = None
        try:
            fresh = type(ident)(window=ident.window, rate=ident.rate, params=ident.params,
                                envelope=ident.envelope)
            fresh.set_state(json.loads(json.dumps(state)))
        except (TypeError, ValueError) as exc:
            problem = str(exc)
            if os.path.exists(target):
                target = beside(target)
        write_state(target, state)
        self.message = (f'learned state written to {target}' if problem is None else
                        f'the learned state would be rejected at the next start ({problem}); '
                        f'written to {target}, the previous file is kept')
        return target
