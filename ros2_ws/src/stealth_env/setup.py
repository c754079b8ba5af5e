from setuptools import find_packages, setup

package_name = 'stealth_env'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='stealth-nav developers',
    maintainer_email='dev@stealth-nav.org',
    description='The RL environment node of stealth-nav (rl_msgs), over stealth_core.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['env_node = stealth_env.env_node:main'],
    },
)
