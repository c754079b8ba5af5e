"""The world model of stealth-nav, without ROS: maps, kinematics, searchlights, occlusion,
rewards, the move lattice, planners, scenarios, sensing, pictures and the Gym environment.

No module of this package imports rclpy or a ROS message package (tests/test_imports.py), so
``pip install ros2_ws/src/stealth_core`` is all a Gymnasium user needs. Importing it registers
``StealthNav-v0`` (``stealth_core.gym_env.StealthNavEnv``) when gymnasium is installed::

    import gymnasium as gym
    import stealth_core

    gym.register_envs(stealth_core)
    env = gym.make('StealthNav-v0', scenario='simple-maze', goal='easy')
"""

ENV_ID = 'StealthNav-v0'

try:
    from gymnasium.envs.registration import register, registry
except ImportError:  # pragma: no cover - gymnasium is a declared dependency
    pass
else:
    if ENV_ID not in registry:
        register(id=ENV_ID, entry_point='stealth_core.gym_env:StealthNavEnv')
