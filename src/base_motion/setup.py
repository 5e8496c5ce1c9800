from setuptools import find_packages, setup

PACKAGE = "base_motion"

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
    description="Node: publishes the moving base's attitude, angular velocity and acceleration.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "base_motion = base_motion.node:main",
            "amb-base-motion = base_motion.node:main",
        ],
    },
)
