from setuptools import find_packages, setup

PACKAGE = "amb_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["fastdds_profile.xml", "fastdds_profile_localhost.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="Shared ROS 2 glue for the amb-rig nodes: DDS environment, QoS, diagnostics, message checks.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [],
    },
)
