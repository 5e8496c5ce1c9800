from setuptools import find_packages, setup

PACKAGE = "amb_bag"

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
    description="MCAP recorder (rosbag2 layout), player, info, check and plot.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["record = amb_bag.recorder:main", "amb-bag = amb_bag.cli:main"],
    },
)
