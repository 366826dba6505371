"""The fast path of :func:`~sins_align_ros.io.bag.read_bag` for rosbag2's sqlite3 storage.

A ``.db3`` recording is one SQLite table of CDR blobs; reading it with the standard
library's ``sqlite3`` and decoding the blobs in bulk (:mod:`.cdr`) replaces the
per-message iteration and type store of ``rosbags``, which took most of a 1200-s
replay's bag read (0.5 s for 120,000 IMU messages, against about 0.3 s here).

Recording order is the storage's: messages sorted by their receive ``timestamp``,
ties in insertion order (``ORDER BY timestamp, id``, which is what an index scan on
the timestamp gives the general reader). The path applies only where it gives
exactly what the general reader would: one uncompressed ``.db3`` file, CDR
serialization, and every message of the topics read decoded here. Anything else
(split or compressed bags, a database error part-way, a message the bulk decoders
do not take) returns None and the caller uses the general ``rosbags`` path, which
also keeps what came before a fault.
"""
import sqlite3
from collections import namedtuple
from operator import itemgetter
from pathlib import Path

import numpy as np

from .bag_data import BagEvent, BagRecording
from .cdr import decode_fix, decode_imu, decode_odometry_q, decode_twist

#: what :func:`~sins_align_ros.io.bag._match` needs of a topic
Topic = namedtuple('Topic', 'id topic msgtype')


def db3_file(path):
    """Return the single uncompressed ``.db3`` file of a rosbag2 at ``path``, else None.

    ``path`` is the ``.db3`` file itself or the bag's folder; a folder with more than
    one storage file (a split recording) or whose metadata names a compression is
    left to the general reader.
    """
    p = Path(path)
    if p.is_file():
        return p if p.suffix == '.db3' else None
    if not p.is_dir():
        return None
    files = [f for f in p.iterdir() if f.suffix != '.yaml']
    meta = p / 'metadata.yaml'
    if len(files) != 1 or files[0].suffix != '.db3' or not meta.is_file():
        return None
    text = meta.read_text(errors='replace')
    if any(line.split(':', 1)[1].strip() not in ('', "''", '""')
           for line in text.splitlines() if line.strip().startswith('compression_format:')):
        return None
    return files[0]


def _query(con, groups):
    """``(timestamps, rowids, blobs)`` of each group of topic ids, in recording order.

    One scan of the table for all the groups (each scan reads every message's pages:
    a 1200-s recording's GNSS topics cost 23 ms a query for 1200 rows), split here by
    topic; each group is sorted by ``(timestamp, id)`` when it is not already in that
    order (an index scan costs as much as the sort it saves).
    """
    ids = sorted({i for g in groups for i in g})
    rows = con.execute(f'SELECT topic_id, timestamp, id, data FROM messages WHERE topic_id '
                       f'IN ({",".join("?" * len(ids))})', tuple(ids)).fetchall() if ids else []
    n = len(rows)
    topic = np.fromiter(map(itemgetter(0), rows), np.int64, n)
    stamp_all = np.fromiter(map(itemgetter(1), rows), np.int64, n)
    rowid_all = np.fromiter(map(itemgetter(2), rows), np.int64, n)
    blobs_all = list(map(itemgetter(3), rows))
    del rows
    parts = []
    for g in groups:
        k = np.flatnonzero(np.isin(topic, list(g))) if len(ids) > len(g) else np.arange(n)
        stamp, rowid = stamp_all[k], rowid_all[k]
        blobs = blobs_all if len(k) == n else [blobs_all[i] for i in k.tolist()]
        d_stamp = np.diff(stamp)
        if not ((d_stamp > 0) | ((d_stamp == 0) & (np.diff(rowid) > 0))).all():
            order = np.lexsort((rowid, stamp))
            stamp, rowid, blobs = stamp[order], rowid[order], [blobs[k] for k in order]
        parts.append((stamp, rowid, blobs))
    return parts


def read_db3(db, select):
    """Read the IMU, GNSS and truth topics of the ``.db3`` file ``db`` at once.

    ``select(topics)`` maps the bag's topics (a list of :data:`Topic`) to the matched
    ``(imu, fix, truth, vel)`` lists (raising ``BagError`` as the general reader does).
    Returns a :class:`~sins_align_ros.io.bag_data.BagRecording`, or None where this path
    does not apply (see the module docstring).
    """
    try:
        con = sqlite3.connect(f'file:{db}?immutable=1', uri=True)
    except sqlite3.Error:
        return None
    try:
        # memory-mapped reads: the pages are not copied into SQLite's cache (fetch -25 %)
        con.execute(f'PRAGMA mmap_size={1 << 34}')
        cols = {r[1] for r in con.execute('PRAGMA table_info(topics)')}
        if not {'id', 'name', 'type', 'serialization_format'} <= cols:
            return None
        listed = con.execute('SELECT id, name, type, serialization_format FROM topics')
        rows = listed.fetchall()
        if any(fmt != 'cdr' for _, _, _, fmt in rows):
            return None
        imu, fix, truth, vel = select([Topic(i, name, ty) for i, name, ty, _ in rows])
        parts = _query(con, [[c.id for c in cs] for cs in (imu, fix, vel, truth)])
    except sqlite3.Error:
        return None
    finally:
        con.close()
    (ts_imu, id_imu, raw_imu), *others = parts
    t, w, f, missing, ok = decode_imu(raw_imu)
    if not ok.all():
        return None
    decoded = [decode_fix(others[0][2]), decode_twist(others[1][2]),
               decode_odometry_q(others[2][2])]
    if not all(d[-1].all() for d in decoded):
        return None
    events = []
    (tf, status, llh, cov, cov_type, _), (tv, v, vcov, _), (tq, q, _) = decoded
    for k in range(len(tf)):
        pos_var = None if cov_type[k] == 0 else (float(cov[k, 0]), float(cov[k, 4]))
        data = (int(status[k]), *map(float, llh[k]), pos_var)
        events.append(BagEvent('fix', float(tf[k]), data))
    for k in range(len(tv)):
        data = (tuple(map(float, v[k])), (float(vcov[k, 0]), float(vcov[k, 7])))
        events.append(BagEvent('vel', float(tv[k]), data))
    for k in range(len(tq)):
        events.append(BagEvent('truth', float(tq[k]), (tuple(map(float, q[k])),)))
    ts_ev = np.concatenate([o[0] for o in others])
    id_ev = np.concatenate([o[1] for o in others])
    order = np.lexsort((id_ev, ts_ev))
    events = [events[k] for k in order]
    ts_ev, id_ev = ts_ev[order], id_ev[order]
    # IMU messages recorded before each event: (timestamp, id) lexicographically smaller
    before = np.searchsorted(ts_imu, ts_ev, side='left')
    tied = np.searchsorted(ts_imu, ts_ev, side='right')
    for j in np.flatnonzero(tied > before):
        before[j] += int(np.count_nonzero(id_imu[before[j]:tied[j]] < id_ev[j]))
    return BagRecording(t, w, f, missing, events, before.astype(int), None)
