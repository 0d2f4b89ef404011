"""ament_python package gnss_ins (also pip-installable for machines without a ROS install)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "gnss_ins"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "bench", "bench.*"]),
    # The EGM96 geoid grid and its source and licence notes (gnss_driver/data/README.md).
    package_data={"gnss_driver": ["data/*.npz", "data/*.md", "data/egm96_LICENSE"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
    ],
    python_requires=">=3.11",
    install_requires=[
        "setuptools",
        "numpy>=1.26",
        "scipy>=1.11",
        "pyserial>=3.5",
        "pynmea2>=1.19",
        # RTCM 3 frames' CRC-24Q (gnss_ins_common/rtcm.py).
        "pyrtcm>=1.2",
        "pymap3d>=3.0",
        "pyproj>=3.6",
        "rosbags>=0.10",
        # Reads MCAP files record by record, as a killed recorder left them (bags/salvage.py).
        "mcap>=1.2",
        "filterpy>=1.4.5",
        "allantools>=2019.9",
        "matplotlib>=3.7",
        "PyYAML>=6.0",
        "gpxpy>=1.6",
        # The engine's per-sample arithmetic, compiled (ins_fusion/core/compiled.py).
        "numba>=0.60",
        # gnss_ins batch and the sweeps of gnss_ins replay run on a Dask cluster
        # (ins_fusion/runtime/cluster.py, docs/fleet.md).
        "dask[distributed]>=2024.8",
    ],
    extras_require={
        "test": [
            # pytest 9.2 changed node ids so that pytest-xdist's --dist loadgroup (make pytest)
            # silently stops grouping (pytest-dev/pytest-xdist#1386).
            "pytest>=8,<9.2",
            "pytest-xdist>=3.5",
            "hypothesis>=6.100",
            "ruff>=0.6",
            "mypy>=1.10",
            "types-PyYAML",
            "colcon-common-extensions>=0.3",
        ],
    },
    zip_safe=True,
    maintainer="gnss_ins maintainers",
    maintainer_email="maintainers@gnss-ins.invalid",
    description="GNSS-aided INS: IMU400CC and NMEA drivers, ESKF fusion, tools.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "imu400cc_node = imu400cc_driver.node:main",
            "gnss_node = gnss_driver.node:main",
            "ntrip_node = ntrip_client.node:main",
            "ins_fusion_node = ins_fusion.node:main",
            "gnss_ins = ins_fusion.tools.cli:main",
        ],
    },
)
