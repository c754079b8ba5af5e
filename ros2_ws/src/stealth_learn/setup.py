from setuptools import find_packages, setup

package_name = 'stealth_learn'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['policies/*.npz', 'policies/*.png']},
    # The learning extra's exact versions live in the repository's requirements.lock; the world
    # model (stealth_core) is not on PyPI: install it from ros2_ws/src/stealth_core first.
    # gymnax (stealth_learn.gymnax_env only) is not required here: it declares gymnasium<1.4
    # against the project's 1.4.0, which `make learn` overrides (requirements-overrides.txt).
    install_requires=[
        'setuptools',
        'stealth_core',
        'numpy',
        'matplotlib',
        'tqdm',
        'jax',
        'flax',
        'optax',
    ],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='stealth-nav developers',
    maintainer_email='dev@stealth-nav.org',
    description='The JAX training environment (equal to StealthTask) and the generalist.',
    license='Apache-2.0',
    # The agent node's policy plugins (stealth_agent.policy_plugins): agent: generalist.
    entry_points={
        'stealth_agent.policies': ['generalist = stealth_learn.ros_policy:load'],
    },
)
