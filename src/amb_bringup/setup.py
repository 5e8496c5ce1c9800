from glob import glob

from setuptools import find_packages, setup

PACKAGE = "amb_bringup"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        ("share/" + PACKAGE + "/launch", sorted(glob("launch/*.launch.py"))),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="amb-rig: starts the nodes as separate processes (no launch system) and summarises a run.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["amb-rig = amb_bringup.rig:main", "amb-live = amb_bringup.live:main"],
    },
)
