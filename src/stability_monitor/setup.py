from setuptools import find_packages, setup

PACKAGE = "stability_monitor"

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
    description="Node and offline CLI: online Floquet multipliers and instability flag.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "monitor = stability_monitor.node:main",
            "amb-monitor = stability_monitor.cli:main",
        ],
    },
)
