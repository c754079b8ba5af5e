from setuptools import find_packages, setup

package_name = 'stealth_sim'

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
    description='Kinematic diff-drive simulator with noisy odometry and localisation.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'image_to_bw = stealth_sim.map_tools:image_to_bw_main',
            'png_to_ros_map = stealth_sim.map_tools:png_to_ros_map_main',
            'render_map = stealth_sim.map_tools:render_map_main',
            'sim_node = stealth_sim.sim_node:main',
        ],
    },
)
