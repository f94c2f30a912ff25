"""Config sections for the network: zenoh session and the injected link impairments."""

from __future__ import annotations

from dataclasses import dataclass

from teleop.config.loader import param, section


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    """How the services find each other over zenoh."""

    mode: str = param("peer", "zenoh session mode", choices=("peer", "client", "router"))
    endpoint: str = param(
        "tcp/127.0.0.1:7447",
        "endpoint the controller listens on and the master and hand connect to (teleop up)",
    )
    listen: tuple[str, ...] = param((), "extra endpoints this service listens on (teleop run)")
    connect: tuple[str, ...] = param((), "extra endpoints this service connects to (teleop run)")
    multicast_scouting: bool = param(False, "enable zenoh multicast scouting")
    liveliness: bool = param(True, "declare a liveliness token per service and watch the peers'")
    shared_clock: bool = param(
        True, "services share one monotonic clock (one machine): injected delays count from "
        "the send time; false: from the arrival time (across machines)")


@dataclass(frozen=True, slots=True)
class LinkConfig:
    """Impairments injected on one link; both directions unless a backward_* key is set."""

    delay_s: float = param(0.0, "constant one-way delay", unit="s", lo=0.0, hi=10.0)
    backward_delay_s: float | None = param(
        None, "one-way delay in the backward direction (unset: same as delay_s)",
        unit="s", lo=0.0, hi=10.0,
    )
    jitter: str = param("none", "jitter distribution added to the delay",
                        choices=("none", "uniform", "normal", "pareto"))
    jitter_s: float = param(0.0, "jitter scale; jitter only adds to delay_s (uniform: in "
                            "[0, jitter_s]; normal: |N(0, jitter_s)|; pareto: Lomax scale, "
                            "shape 2.5)", unit="s", lo=0.0, hi=10.0)
    loss: float = param(0.0, "packet loss probability (mean rate for gilbert)", lo=0.0, hi=1.0)
    loss_model: str = param("bernoulli", "loss process", choices=("bernoulli", "gilbert"))
    burst_length: float = param(5.0, "mean burst length of the Gilbert-Elliott loss process",
                                unit="messages", lo=1.0, hi=1e6)
    duplicate: float = param(0.0, "probability a message is delivered twice", lo=0.0, hi=1.0)
    reorder: bool = param(True, "allow jitter to reorder messages (false: FIFO per link)")
    seed: int = param(0, "random seed of this link's impairments", lo=0)


@dataclass(frozen=True, slots=True)
class LinksConfig:
    """Per-link impairments: forward is master->controller and controller->hand."""

    master_controller: LinkConfig = section(LinkConfig, "master <-> controller link")
    controller_hand: LinkConfig = section(LinkConfig, "controller <-> hand link")
