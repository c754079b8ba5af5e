from glob import glob

from setuptools import find_packages, setup

package_name = 'stealth_nav2'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='stealth-nav developers',
    maintainer_email='dev@stealth-nav.org',
    description="stealth-nav behind Nav2's own interfaces: a covert planner server, a navigator "
    "and an exposure mask for Nav2's costmap filters.",
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'exposure_mask = stealth_nav2.exposure_mask_node:main',
            'navigator = stealth_nav2.navigator_node:main',
            'planner_server = stealth_nav2.planner_node:main',
        ],
    },
)
