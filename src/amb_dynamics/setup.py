from setuptools import find_packages, setup

PACKAGE = "amb_dynamics"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["data/*.yaml"]},  # the seed rotor (a link to config/seed_rotor.yaml)
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="ROS-free numerical core of amb-rig: FE rotor on AMBs on a moving base, Floquet, Newmark.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["amb-dynamics = amb_dynamics.cli:main"],
    },
)
