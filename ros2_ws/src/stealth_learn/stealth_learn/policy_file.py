"""The generalist's weights file: one ``.npz`` (5 KB: the network has ~700 parameters) with
the parameters and a JSON header naming the observation layout, the track and the architecture,
so a policy trained for another layout or track is refused at load naming both layouts, and a
missing or corrupt file is named with its path (issue 30's bad-input rules).

The layout is the grid layout without its size (``stealth-grid-v1/full``): the network is
fully convolutional, so any scenario's grid fits.
"""

from __future__ import annotations

import json
from pathlib import Path
import zipfile

import numpy as np

from stealth_learn.obs_layout import check_layout, layout_id

FORMAT = 'stealth-generalist-v1'
SHIPPED = Path(__file__).resolve().parent / 'policies' / 'generalist-full.npz'  # lights known
HEADER = '__header__'
ARCHITECTURE = ('iterations', 'hidden', 'features', 'threshold')


class PolicyFileError(ValueError):
    """A weights file that is missing, unreadable or not a generalist's."""


def policy_layout(track: str) -> str:
    """The generalist's layout for a track: the grid layout of any size."""
    return without_size(layout_id('grid', track, 0, 0))


def without_size(layout: str) -> str:
    parts = layout.split('/')
    return '/'.join(parts[:2]) if parts[0].startswith('stealth-grid-') else layout


def save(path, params, track: str, architecture: dict, extra: dict | None = None) -> Path:
    """Write ``params`` (a flax params tree) with the header; returns the path."""
    path = Path(path)
    header = {
        'format': FORMAT,
        'layout': policy_layout(track),
        'track': track,
        'architecture': {name: architecture[name] for name in ARCHITECTURE},
        **(extra or {}),
    }
    arrays = {f'params/{key}': np.asarray(value) for key, value in _flatten(params).items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open('wb') as stream:
        np.savez_compressed(stream, **arrays, **{HEADER: np.array(json.dumps(header))})
    return path


def load(path, env_layout: str) -> tuple[dict, dict]:
    """(params tree, header) of the file at ``path`` for an environment giving ``env_layout``
    (``obs_layout.layout_id``: any grid size). PolicyFileError (missing, corrupt) or
    ``obs_layout.LayoutError`` (another layout or track), one line each, naming the path."""
    path = Path(path)
    if not path.is_file():
        raise PolicyFileError(
            f'{path}: no such policy file (train one: python -m '
            'stealth_learn.train_generalist --help)'
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(str(data[HEADER]))
            flat = {
                k[len('params/') :]: np.asarray(data[k])
                for k in data.files
                if k.startswith('params/')
            }
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as error:
        raise PolicyFileError(
            f'{path}: not a readable generalist policy file ({type(error).__name__}: {error})'
        ) from None
    if not isinstance(header, dict) or header.get('format') != FORMAT or not flat:
        raise PolicyFileError(f'{path}: not a generalist policy file (expected format {FORMAT})')
    architecture = header.get('architecture')
    if not isinstance(architecture, dict) or set(architecture) != set(ARCHITECTURE):
        raise PolicyFileError(
            f'{path}: header field architecture: expected {", ".join(ARCHITECTURE)}'
        )
    check_layout(str(header.get('layout')), without_size(env_layout), str(path))
    return _unflatten(flat), header


def _flatten(tree, prefix: str = '') -> dict:
    out = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict) or hasattr(value, 'items'):
            out.update(_flatten(value, name + '/'))
        else:
            out[name] = value
    return out


def _unflatten(flat: dict) -> dict:
    tree: dict = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split('/')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree
