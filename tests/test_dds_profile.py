"""The chain's Fast DDS profile: set for every start, valid, and harmless to peers without it.

The profile (src/stereo_fuzzy_perception/config/fastdds_large_messages.xml) gives each process a
shared-memory segment that holds a stereo pair and its matches; what that buys in latency is
measured by benchmarks/chain_latency_benchmark.py, not here.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
from ros_waiting import wait_until
from stereo_fuzzy_perception.bringup.chain_description import (
    DDS_PROFILES_FILE,
    DDS_PROFILES_VARIABLE,
)

REPO_ROOT = Path(__file__).resolve().parents[1]
PROFILE = REPO_ROOT / 'src' / 'stereo_fuzzy_perception' / 'config' / DDS_PROFILES_FILE
PEER = REPO_ROOT / 'tests' / 'support' / 'large_message_peer.py'
NAMESPACE = {'dds': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
STEREO_PAIR_BYTES = 2 * 640 * 480


def profile_seen_by_env_sh(given: str | None) -> str:
    environment = {key: value for key, value in os.environ.items()
                   if key != DDS_PROFILES_VARIABLE}
    if given is not None:
        environment[DDS_PROFILES_VARIABLE] = given
    result = subprocess.run(
        ['bash', '-c', f'source scripts/env.sh >/dev/null && echo "${DDS_PROFILES_VARIABLE}"'],
        cwd=REPO_ROOT, env=environment, capture_output=True, text=True, check=True)
    return result.stdout.strip()


def test_env_sh_sets_the_profile_unless_the_user_has_one():
    assert profile_seen_by_env_sh(None) == str(PROFILE)
    assert profile_seen_by_env_sh('/my/own/profile.xml') == '/my/own/profile.xml'


def test_the_profile_is_the_default_transports_with_a_segment_for_several_pairs():
    root = ElementTree.parse(PROFILE).getroot()
    participant = root.find('dds:participant', NAMESPACE)
    assert participant is not None and participant.get('is_default_profile') == 'true'
    used = [element.text for element in participant.findall(
        'dds:rtps/dds:userTransports/dds:transport_id', NAMESPACE)]
    assert participant.findtext('dds:rtps/dds:useBuiltinTransports', None, NAMESPACE) == 'false'
    kinds = {descriptor.findtext('dds:transport_id', None, NAMESPACE):
             (descriptor.findtext('dds:type', None, NAMESPACE), descriptor)
             for descriptor in root.findall('dds:transport_descriptors/dds:transport_descriptor',
                                            NAMESPACE)}
    # Fast DDS's built-in default is shared memory on this host and UDPv4 to the others.
    assert sorted(kinds[name][0] for name in used) == ['SHM', 'UDPv4']
    shared = next(descriptor for kind, descriptor in kinds.values() if kind == 'SHM')
    # a reliable topic keeps a few messages in flight: several pairs and their matches
    assert int(shared.findtext('dds:segment_size', '0', NAMESPACE)) >= 8 * STEREO_PAIR_BYTES


@pytest.mark.ros
@pytest.mark.parametrize('profiled', ['publisher', 'receiver'])
def test_large_messages_cross_between_a_process_with_the_profile_and_one_without(
        ros_domain_id, profiled):
    size = 4 * STEREO_PAIR_BYTES  # larger than the default segment, well inside ours
    without = {key: value for key, value in os.environ.items() if key != DDS_PROFILES_VARIABLE}
    with_profile = dict(without, **{DDS_PROFILES_VARIABLE: str(PROFILE)})
    publisher = subprocess.Popen(
        [sys.executable, str(PEER), 'publish', str(size)],
        env=with_profile if profiled == 'publisher' else without,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    receiver = subprocess.Popen(
        [sys.executable, str(PEER), 'receive', str(size), '5'],
        env=with_profile if profiled == 'receiver' else without,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        wait_until(lambda: receiver.poll() is not None, 120.0,
                   '5 large messages received')
        output = receiver.stdout.read() if receiver.stdout else ''
        assert receiver.returncode == 0, output
        assert 'received 5 intact, broken: []' in output
    finally:
        # SIGINT, so that each peer removes its shared-memory segment as it ends
        for process in (receiver, publisher):
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        for process in (receiver, publisher):
            try:
                process.wait(timeout=20.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for process in (receiver, publisher):
            if process.stdout:
                process.stdout.close()
