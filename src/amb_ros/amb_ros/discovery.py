"""How far DDS discovery reaches: localhost by default, wider only when the user asks (no ROS imports).

ROS 2 Jazzy reads two variables when a process starts DDS: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (``LOCALHOST``,
``SUBNET``, ``SYSTEM_DEFAULT``, ``OFF``; rcl silently treats any other value as LOCALHOST) and ``ROS_STATIC_PEERS``
(hosts separated by ``;``, contacted by unicast in addition to the range).  Every process of the project honours
what the user set, checks it first (a typo is refused with one line instead of silently meaning something else)
and says once, on one line, when discovery reaches beyond this machine.  ``amb-rig run --discovery`` writes the
same two variables (:func:`choice_env`).  Tests, ``make demo``, ``make bench`` and CI force LOCALHOST.
"""

from __future__ import annotations

import ipaddress
import re
from dataclasses import dataclass

RANGE_VAR, PEERS_VAR = "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS"
LOCALHOST, SUBNET, SYSTEM_DEFAULT = "LOCALHOST", "SUBNET", "SYSTEM_DEFAULT"
RANGES = (LOCALHOST, SUBNET, SYSTEM_DEFAULT)
CHOICES = "localhost, subnet or peers:HOST[,HOST...]"
_LABEL = re.compile(r"^[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?$")


class DiscoveryError(ValueError):
    """A discovery setting that is not one of the values ROS 2 understands (the message names it)."""


@dataclass(frozen=True)
class Discovery:
    """The effective discovery of a process: the range and the static peers (host names or addresses)."""

    range: str = LOCALHOST
    peers: tuple[str, ...] = ()

    @property
    def localhost_only(self) -> bool:
        return self.range == LOCALHOST and not self.peers

    def describe(self) -> str:
        if self.range == SUBNET:
            where = "every host on the local subnets (multicast)"
        elif self.range == SYSTEM_DEFAULT:
            where = "wherever the DDS implementation's defaults reach (multicast on every interface)"
        else:
            where = "this machine"
        if self.peers:
            where += f" and the static peers {', '.join(self.peers)}"
        return where

    def warning(self) -> str:
        """The one warning line for a discovery wider than localhost."""
        peers = f" {PEERS_VAR}={';'.join(self.peers)}" if self.peers else ""
        return (
            f"warning: DDS discovery reaches {self.describe()} ({RANGE_VAR}={self.range}{peers}): any node on the "
            "same ROS_DOMAIN_ID there can read and write this rig's topics"
        )


def valid_host(host: str) -> bool:
    """An IPv4/IPv6 address or a DNS host name (RFC 1123 labels); all-numeric names must be IPv4 addresses."""
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        pass
    if not host or len(host) > 253 or re.fullmatch(r"[0-9.]+", host):
        return False
    return all(_LABEL.match(label) for label in host.rstrip(".").split("."))


def parse_peers(text: str, sep: str = ";", what: str = PEERS_VAR) -> tuple[str, ...]:
    """The hosts in ``text`` (separated by ``sep``); empty entries are ignored, bad ones refused."""
    peers = tuple(p.strip() for p in text.split(sep) if p.strip())
    for peer in peers:
        if not valid_host(peer):
            raise DiscoveryError(f"{what}={text}: {peer!r} is not a host name or an IP address")
    return peers


def resolve(env) -> Discovery:
    """The discovery ``env`` asks for (LOCALHOST when unset); raise DiscoveryError for values ROS 2 ignores."""
    raw = env.get(RANGE_VAR, "").strip()
    value = raw.upper() or LOCALHOST
    if value == "OFF":
        raise DiscoveryError(f"{RANGE_VAR}=OFF: the rig's nodes could not find each other; use LOCALHOST or unset it")
    if value not in RANGES:
        raise DiscoveryError(f"{RANGE_VAR}={raw}: expected one of {', '.join(RANGES)} (unset means LOCALHOST)")
    return Discovery(value, parse_peers(env.get(PEERS_VAR, "")))


def choice_env(choice: str) -> dict[str, str | None]:
    """The variables for ``amb-rig run --discovery CHOICE`` (None: unset the variable)."""
    text = choice.strip()
    if text.lower() == "localhost":
        return {RANGE_VAR: LOCALHOST, PEERS_VAR: None}
    if text.lower() == "subnet":
        return {RANGE_VAR: SUBNET, PEERS_VAR: None}
    if text.lower().startswith("peers:"):
        peers = parse_peers(text[len("peers:") :], sep=",", what="--discovery peers:")
        if not peers:
            raise DiscoveryError(f"--discovery {choice}: name at least one host after 'peers:'")
        return {RANGE_VAR: LOCALHOST, PEERS_VAR: ";".join(peers)}
    raise DiscoveryError(f"--discovery {choice}: expected {CHOICES}")


def apply_choice(choice: str | None, env) -> None:
    """Write ``--discovery CHOICE`` into ``env`` (None: leave the user's environment as it is)."""
    if choice is None:
        return
    for var, value in choice_env(choice).items():
        if value is None:
            env.pop(var, None)
        else:
            env[var] = value
