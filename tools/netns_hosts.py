#!/usr/bin/env python3
"""Two "hosts" on one machine: two network namespaces joined by a veth pair (Linux, root).

Each namespace has its own interfaces, addresses, routes and UDP ports, so DDS discovery and
data between them cross the veth link as they would cross a cable between two computers.
Used by ``test/test_across_hosts.py`` and, by hand, by ``docs/guides/across-hosts.md``.

Host ``a`` gets ``<subnet>.1/24`` on its end of the veth, host ``b`` ``<subnet>.2/24``; both
bring ``lo`` up (a fresh namespace has it down: nothing on 127.0.0.1 works, not even a
node talking to itself over UDP). No multicast route is added: a fresh namespace has no
default route, and Fast DDS's multicast discovery crossed the link without one (checked).

``routed=True`` puts a router between them instead, as between two subnets of a plant: a
third namespace ``<name>-r`` forwards IPv4 between ``<subnet>.0/24`` (host ``a`` at ``.1``)
and the next /24 (host ``b`` at ``.2``), each host's default route pointing at it (``.254``).
Unicast crosses; multicast does not (Linux forwards no multicast without a multicast
routing daemon, and DDS sends it with a TTL of 1), so only static peers connect the hosts.
(A filter dropping multicast on one link would show the same, but this kernel has no
``tc`` drop action.)

A command run with :meth:`TwoHosts.command` also sees its host's own ``/dev/shm``: a directory
``/dev/shm/netns-<namespace>`` bind-mounted over ``/dev/shm`` in a mount namespace of its
own, shared by every command of that host and by no other. Two real hosts share no memory,
and Fast DDS moves data through shared memory (``/dev/shm/fastrtps_*``) between participants
it believes are on one host; one ``/dev/shm`` per process instead breaks that transport
between two processes of one host (with ``LOCALHOST`` nothing arrived).

Names are unique per object (a prefix, the process id and a counter), so parallel runs do not
collide (the addresses may repeat: each pair lives in namespaces of its own).
:meth:`TwoHosts.destroy` is idempotent, runs on ``with`` exit and at interpreter exit
(``atexit``), ends the processes still running inside its namespaces, and deletes them
(deleting a namespace deletes the veth end inside it, and so the pair). Those of a process
killed before its ``atexit`` ran are removed by the next :meth:`TwoHosts.create`.

From the command line (namespaces that outlive the command; ``down`` removes them)::

    tools/netns_hosts.py up --name demo      # prints the names and addresses
    tools/netns_hosts.py exec --name demo a -- ip -br addr
    tools/netns_hosts.py down --name demo
    tools/netns_hosts.py check               # can this machine make them? (exit 0: yes)
"""
from __future__ import annotations

import argparse
import atexit
import itertools
import os
import re
import shutil
import signal
import subprocess
import sys
import time

#: runs a command with its host's /dev/shm: ``sh -c SHM_WRAPPER <host's dir> <argv...>``
SHM_WRAPPER = 'mount --bind "$0" /dev/shm && exec "$@"'

_COUNTER = itertools.count()


def _ip(*args, check=True):
    """Run ``ip <args>``; return the completed process (stdout, stderr as text)."""
    return subprocess.run(['ip', *args], capture_output=True, text=True, check=check)


def unavailable_reason():
    """Why two namespaces cannot be made here, or None when they can.

    Returns
    -------
    str or None
        A sentence naming what is missing (not root, no ``ip``, no ``unshare``, namespaces
        refused by the kernel or the container); None when a test namespace was made and
        deleted.
    """
    if not sys.platform.startswith('linux'):
        return f'network namespaces are Linux only (this is {sys.platform})'
    if os.geteuid() != 0:
        return 'creating network namespaces needs root (ip netns add)'
    for tool in ('ip', 'unshare', 'mount', 'sysctl'):
        if shutil.which(tool) is None:
            return f'no `{tool}` command (iproute2 / util-linux) on PATH'
    probe = f'idsprobe{os.getpid()}'
    r = _ip('netns', 'add', probe, check=False)
    if r.returncode != 0:
        return f'`ip netns add` refused: {r.stderr.strip()}'
    try:
        r = _ip('link', 'add', f'{probe}a', 'type', 'veth', 'peer', 'name', f'{probe}b',
                check=False)
        if r.returncode != 0:
            return f'`ip link add type veth` refused: {r.stderr.strip()}'
        _ip('link', 'del', f'{probe}a', check=False)
        r = subprocess.run(['ip', 'netns', 'exec', probe, 'unshare', '-m', 'sh', '-c',
                            SHM_WRAPPER, '/dev/shm', 'true'], capture_output=True, text=True)
        if r.returncode != 0:
            return f'a /dev/shm per host (unshare -m, mount --bind) failed: {r.stderr.strip()}'
    finally:
        _ip('netns', 'del', probe, check=False)
    return None


def remove_stale():
    """Delete the namespaces (and /dev/shm directories) of default-named :class:`TwoHosts`
    whose process is gone (killed before its ``atexit`` ran); return their names."""
    stale = []
    for line in _ip('netns', 'list').stdout.splitlines():
        match = re.fullmatch(r'(ids(\d+)x\d+)-[abr]', line.split(' ')[0])
        if match and not os.path.exists(f'/proc/{match.group(2)}'):
            _ip('netns', 'del', match.group(0), check=False)
            shutil.rmtree(f'/dev/shm/netns-{match.group(0)}', ignore_errors=True)
            stale.append(match.group(0))
    return stale


class TwoHosts:
    """Two network namespaces ``a`` and ``b`` joined by a veth pair.

    Parameters
    ----------
    name : str, optional
        Base of the names (namespaces ``<name>-a``, ``<name>-b``, ``<name>-r``; veth ends
        ``<name>a``, ``<name>b``, ``<name>ra``, ``<name>rb``, so at most 13 characters).
        Default: ``ids<pid>x<n>``, unique per object of this process.
    subnet : str
        First three octets of host a's /24 (host b's too unless ``routed``).
    routed : bool
        Two subnets joined by a router namespace instead of one link.
    persistent : bool
        Do not destroy at interpreter exit (the command line's ``up``).

    Attributes
    ----------
    namespaces : dict of str to str
        ``{'a': ..., 'b': ...}``, the hosts' namespace names.
    addresses : dict of str to str
        The hosts' addresses: ``{'a': '<subnet>.1', 'b': '<subnet>.2'}``; routed, host b's
        third octet is one more (``10.231.1.2`` for ``10.231.0``).
    """

    def __init__(self, name=None, subnet='10.231.0', routed=False, persistent=False):
        name = name or f'ids{os.getpid()}x{next(_COUNTER)}'
        if len(name) > 13:
            raise ValueError(f'name {name!r}: at most 13 characters (interface names are '
                             'at most 15)')
        self.name = name
        self.routed = routed
        self.namespaces = {'a': f'{name}-a', 'b': f'{name}-b'}
        self.router = f'{name}-r'
        self.veths = {'a': f'{name}a', 'b': f'{name}b'}
        self.shm = {host: f'/dev/shm/netns-{ns}' for host, ns in self.namespaces.items()}
        first, second, third = subnet.split('.')
        self.subnets = {'a': subnet,
                        'b': f'{first}.{second}.{int(third) + 1}' if routed else subnet}
        self.addresses = {'a': f'{self.subnets["a"]}.1', 'b': f'{self.subnets["b"]}.2'}
        self._atexit = not persistent

    def _all_namespaces(self):
        return [*self.namespaces.values(), self.router]

    def exists(self):
        """True when any of the namespaces exists."""
        listed = _ip('netns', 'list').stdout.split()
        return any(ns in listed for ns in self._all_namespaces())

    def create(self):
        """Make the namespaces and the links; a leftover of the same name is removed first.

        Returns
        -------
        TwoHosts
            self.
        """
        self.destroy()
        remove_stale()
        if self._atexit:
            atexit.register(self.destroy)
        try:
            for host, ns in self.namespaces.items():
                _ip('netns', 'add', ns)
                _ip('-n', ns, 'link', 'set', 'lo', 'up')
                os.mkdir(self.shm[host])
                os.chmod(self.shm[host], 0o1777)   # as /dev/shm itself
            if self.routed:
                self._create_routed()
            else:
                _ip('link', 'add', self.veths['a'], 'type', 'veth', 'peer', 'name',
                    self.veths['b'])
            for host, ns in self.namespaces.items():
                veth = self.veths[host]
                _ip('link', 'set', veth, 'netns', ns)
                _ip('-n', ns, 'addr', 'add', f'{self.addresses[host]}/24', 'dev', veth)
                _ip('-n', ns, 'link', 'set', veth, 'up')
                if self.routed:
                    _ip('-n', ns, 'route', 'add', 'default', 'via',
                        f'{self.subnets[host]}.254')
        except BaseException:
            self.destroy()
            raise
        return self

    def _create_routed(self):
        """The router namespace, one veth pair to each host (hosts' ends left in the root)."""
        _ip('netns', 'add', self.router)
        _ip('-n', self.router, 'link', 'set', 'lo', 'up')
        subprocess.run(['ip', 'netns', 'exec', self.router, 'sysctl', '-qw',
                        'net.ipv4.ip_forward=1'], check=True, capture_output=True)
        for host in 'ab':
            inner = f'{self.name}r{host}'
            _ip('link', 'add', self.veths[host], 'type', 'veth', 'peer', 'name', inner)
            _ip('link', 'set', inner, 'netns', self.router)
            _ip('-n', self.router, 'addr', 'add', f'{self.subnets[host]}.254/24', 'dev', inner)
            _ip('-n', self.router, 'link', 'set', inner, 'up')

    def pids(self):
        """Process ids running in either namespace (list of int)."""
        found = []
        for ns in self._all_namespaces():
            r = _ip('netns', 'pids', ns, check=False)
            found += [int(p) for p in r.stdout.split()]
        return found

    def destroy(self, grace=3.0):
        """End the processes inside (SIGTERM, SIGKILL after ``grace`` s) and delete the
        namespaces; no error when they are gone already."""
        pids = self.pids()
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for pid in pids:
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass
            end = time.monotonic() + grace
            while pids and time.monotonic() < end:
                pids = [p for p in pids if os.path.exists(f'/proc/{p}')]
                time.sleep(0.05)
            if not pids:
                break
        for ns in self._all_namespaces():
            _ip('netns', 'del', ns, check=False)   # takes its veth ends, and so the pairs
        for veth in self.veths.values():   # a pair left in the root namespace by a failure
            _ip('link', 'del', veth, check=False)
        for path in self.shm.values():
            shutil.rmtree(path, ignore_errors=True)

    def command(self, host, argv, host_shm=True):
        """The argv that runs ``argv`` on ``host`` ('a' or 'b').

        Parameters
        ----------
        host : str
            'a' or 'b'.
        argv : list of str
            The command.
        host_shm : bool
            Give it its host's /dev/shm (see the module's docstring), not the machine's.
        """
        prefix = ['ip', 'netns', 'exec', self.namespaces[host]]
        if host_shm:
            prefix += ['unshare', '-m', 'sh', '-c', SHM_WRAPPER, self.shm[host]]
        return prefix + list(argv)

    def popen(self, host, argv, host_shm=True, **kwargs):
        """Start ``argv`` on ``host`` (:class:`subprocess.Popen`, ``kwargs`` passed on)."""
        return subprocess.Popen(self.command(host, argv, host_shm), **kwargs)

    def run(self, host, argv, host_shm=True, **kwargs):
        """Run ``argv`` on ``host`` to its end (:func:`subprocess.run`, ``kwargs`` passed on)."""
        return subprocess.run(self.command(host, argv, host_shm), **kwargs)

    def link_counters(self, host):
        """Packets and bytes the veth end of ``host`` received and sent.

        Returns
        -------
        dict of str to int
            ``rx_packets``, ``rx_bytes``, ``tx_packets``, ``tx_bytes`` (packets, bytes).
        """
        base = f'/sys/class/net/{self.veths[host]}/statistics'
        out = self.run(host, ['cat', f'{base}/rx_packets', f'{base}/rx_bytes',
                              f'{base}/tx_packets', f'{base}/tx_bytes'],
                       host_shm=False, capture_output=True, text=True, check=True)
        values = [int(v) for v in out.stdout.split()]
        return dict(zip(('rx_packets', 'rx_bytes', 'tx_packets', 'tx_bytes'), values))

    def __enter__(self):
        return self.create()

    def __exit__(self, *exc):
        self.destroy()
        return False


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest='action', required=True)
    up = sub.add_parser('up', help='make the namespaces and the link (they stay until down)')
    up.add_argument('--routed', action='store_true',
                    help='two subnets and a router between them (only static peers cross)')
    up.add_argument('--subnet', default='10.231.0', help='first three octets of the /24')
    for p in (up, sub.add_parser('down', help='remove them (and end what runs inside)'),
              ex := sub.add_parser('exec', help='run a command on host a or b')):
        p.add_argument('--name', default='idsim', help='base of the names (default idsim)')
    ex.add_argument('--shared-shm', action='store_true',
                    help="keep the machine's /dev/shm (default: the host's own)")
    ex.add_argument('host', choices=('a', 'b'))
    ex.add_argument('argv', nargs=argparse.REMAINDER, help='-- command ...')
    sub.add_parser('check', help='say whether namespaces can be made here')
    args = parser.parse_args(argv)

    if args.action == 'check':
        reason = unavailable_reason()
        print(reason or 'network namespaces and veth pairs can be made here')
        return 1 if reason else 0
    if args.action == 'up':
        hosts = TwoHosts(args.name, subnet=args.subnet,
                         routed=args.routed, persistent=True).create()
        for host in 'ab':
            print(f'host {host}: namespace {hosts.namespaces[host]}, '
                  f'{hosts.veths[host]} {hosts.addresses[host]}/24')
        if args.routed:
            print(f'router: namespace {hosts.router}, {hosts.subnets["a"]}.254 and '
                  f'{hosts.subnets["b"]}.254')
        return 0
    hosts = TwoHosts(args.name, persistent=True)
    if args.action == 'down':
        hosts.destroy()
        return 0
    argv = args.argv[1:] if args.argv[:1] == ['--'] else args.argv
    if not argv:
        parser.error('exec: give a command after --')
    # exec, not a child: a signal sent to this command reaches the command run on the host
    command = hosts.command(args.host, argv, host_shm=not args.shared_shm)
    os.execvp(command[0], command)


if __name__ == '__main__':
    sys.exit(main())
