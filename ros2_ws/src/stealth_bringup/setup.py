from setuptools import find_packages, setup

package_name = 'stealth_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (
            'share/' + package_name + '/config',
            [
                'config/agent.yaml',
                'config/bridge.yaml',
                'config/environment.yaml',
                'config/recorder.yaml',
                'config/simulator.yaml',
            ],
        ),
    ],
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='stealth-nav developers',
    maintainer_email='dev@stealth-nav.org',
    description="Orchestrated runs (stealth train/rollout) and the nodes' parameter files.",
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_env = stealth_bringup.sim_env:main',
        ],
        # `stealth train|rollout|eval|render|doctor`: stealth_tools' `stealth` reads this group.
        'stealth.commands': ['stealth_bringup = stealth_bringup.commands:COMMANDS'],
    },
)
