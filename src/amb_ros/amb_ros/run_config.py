"""The run's effective rotor config as a message: the plant publishes it latched on /amb_plant/config (one JSON
object, std_msgs/String), so that every recording of the run carries it and offline tools use it rather than the
current default config (amb_bag.runconfig reads it back from a bag)."""

from __future__ import annotations

import json

from amb_dynamics.config import RotorConfig, config_from_dict, to_dict


def config_json(cfg: RotorConfig) -> str:
    return json.dumps(to_dict(cfg), sort_keys=True)


def config_from_json(text: str, source: str) -> RotorConfig:
    """The config of ``text`` (validated as a config file is; errors name ``source``)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        from amb_dynamics.errors import InputError

        raise InputError(f"{source}: not a JSON config ({exc.msg} at line {exc.lineno})") from None
    return config_from_dict(data, source)
