from setuptools import find_packages, setup

PACKAGE = "amb_plant"

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
    description="Node: flexible rotor on AMBs (sampled-data propagator of amb_dynamics); /clock master in lockstep.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["plant = amb_plant.node:main", "amb-plant = amb_plant.node:main"],
    },
)
