import sys

from setuptools import find_packages, setup

PACKAGE = "amb_controller"
# the short ``ros2 run`` names go to lib/<pkg> (setup.cfg install_scripts), where ros2 run looks; they are made only
# by colcon's ``setup.py install``/``develop``, never by pip, so that only amb-* commands land on the venv's PATH
ROS_RUN = ["controller = amb_controller.node:main"] if {"install", "develop"} & set(sys.argv) else []

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="Node: fixed-rate digital PID per AMB axis.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["amb-controller = amb_controller.node:main", *ROS_RUN],
    },
)
