"""The learning extra, imported in one place: ``from stealth_learn.jax_deps import jax, jnp``
either works or raises ``MissingExtraError``, one line saying how to install it (jax, flax and
optax are ~400 MB of wheels that ``make setup`` leaves out)."""

from __future__ import annotations

INSTALL_HINT = (
    'make learn (or: .venv/bin/uv pip install -r requirements-learn.in -c requirements.lock '
    '--override requirements-overrides.txt)'
)


class MissingExtraError(ImportError):
    """The learning extra (jax, flax, optax) is not installed."""


try:
    from flax import linen as nn
    from flax import struct
    import jax
    import jax.numpy as jnp
except ImportError as error:  # one line, not the import machinery's traceback chain
    missing = getattr(error, 'name', None) or 'jax'
    raise MissingExtraError(
        f'stealth_learn needs the learning extra (jax, flax, optax; {missing} is missing): '
        f'install it with {INSTALL_HINT}'
    ) from None

__all__ = ['INSTALL_HINT', 'MissingExtraError', 'jax', 'jnp', 'nn', 'struct']
