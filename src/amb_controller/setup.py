from setuptools import find_packages, setup

PACKAGE = "amb_controller"

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
        "console_scripts": [
            "controller = amb_controller.node:main",
            "amb-controller = amb_controller.node:main",
        ],
    },
)
