"""The platform's hot classes keep the attributes the loop reads in slots (read without the
instance dict): a slot is only what a read sees when no class before it in the MRO defines the
same name, and an instance keeps its ``__dict__`` for everything else (a subclass's, a user's)."""

from __future__ import annotations

import pytest

from rasm import Platform
from rasm.comm.local import LocalTransport
from rasm.comm.topics import TopicIndex
from rasm.comm.transport import Transport
from rasm.knowledge.base import KnowledgeBase
from rasm.knowledge.redis import RedisKnowledgeBase
from rasm.platform.adaptation_orchestrator import AdaptationOrchestrator
from rasm.platform.block import Block
from rasm.platform.communication_manager import CommunicationManager
from rasm.platform.knowledge_manager import KnowledgeManager
from rasm.platform.scheduler import Scheduler
from rasm.platform.state_manager import StateManager
from rasm.platform.telegraf import Telegraf
from rasm.platform.trace import TraceWriter
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from tests.slots import shadowed_slots, slot_names

from .conftest import HOTBOX

CLASSES = [
    Block,
    AdaptationOrchestrator,
    CommunicationManager,
    KnowledgeManager,
    StateManager,
    Telegraf,
    TrustworthinessChecker,
    Platform,
    Scheduler,
    TraceWriter,
    KnowledgeBase,
    RedisKnowledgeBase,
    Transport,
    LocalTransport,
    TopicIndex,
]


@pytest.mark.parametrize("klass", CLASSES)
def test_no_slot_is_shadowed_by_a_class_attribute(klass: type) -> None:
    assert shadowed_slots(klass) == []


@pytest.mark.parametrize("klass", CLASSES)
def test_instances_keep_a_dict_and_weak_references(klass: type) -> None:
    assert "__dict__" in dir(klass) and "__weakref__" in dir(klass)


def test_every_slot_is_set_once_the_platform_is_built() -> None:
    platform = Platform(HOTBOX, clock="simulated", knowledge="memory")
    platform.build()
    objects = [platform, platform.ao, platform.cm, platform.km, platform.sm, platform.tg,
               platform.tc, platform.scheduler, platform.trace, platform.kb, platform.transport,
               platform.transport._index]
    assert {type(obj) for obj in objects} == set(CLASSES) - {Block, RedisKnowledgeBase, Transport}
    for obj in objects:
        for name in slot_names(type(obj)):
            getattr(obj, name)  # AttributeError for a slot never set
            assert name not in vars(obj)  # nor is a slot's name in the instance dict


def test_a_subclass_keeps_its_own_attributes_and_class_defaults() -> None:
    class Mine(Telegraf):
        digested = 5  # a subclass's class default of a slot's name: the instance's value wins
        extra = "class"

    block = Mine([], lambda values, time: None)
    block.extra = "mine"
    block.own = 1
    assert (block.digested, block.extra, block.own) == (0, "mine", 1)
    assert vars(block) == {"digested": 0, "extra": "mine", "own": 1, "logs": block.logs}
