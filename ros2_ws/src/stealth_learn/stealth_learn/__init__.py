"""stealth_learn: learning across buildings (issue 30). ``env_tables`` (numpy) turns a scenario
into padded tables; ``jax_env`` steps them as pure JAX functions (jit, vmap); ``obs_layout``
names the observation's layout. jax, flax and optax are the learning extra: ``make learn``."""
