"""A fast path for the few topics a run needs from a large ULog (numpy; pyulog for the formats).

pyulog parses every message of a log in Python, the topics it keeps and the ones it filters out
alike: 20 s for a 30-minute, 100 MiB flight log on a loaded 2-core machine. Here the message
headers are walked in a tight loop that only notes where the wanted topics' data messages are;
their payloads are then joined and read with numpy in one go, with the dtype pyulog builds from the
log's own format definitions (so field names, nesting and padding are pyulog's). A log this path
does not handle exactly as pyulog would (a corrupt or unknown message, a data
message of an unexpected size) returns None, and the caller reads it with pyulog. Appended data
(PX4 writes it after the log is closed) is walked range by range, as pyulog reads it.
"""

from __future__ import annotations

import types

import numpy as np

__all__ = ["read_topics"]

_KNOWN = frozenset(b"BFIMPQARDLCSO")
_A, _D, _O = ord("A"), ord("D"), ord("O")
_CHUNK = 65536


def _walk(buf: bytes, ranges, wanted_names, formats, ULog):
    """(subscriptions {msg_id: AddLogged}, {msg_id: [positions]}, dropout ms list) or None.
    ``ranges``: (start, end) byte ranges read in turn (pyulog's order for appended data: a
    message that would cross the end of its range ends the range)."""
    subs, pos_of, dropouts = {}, {}, []
    for start, end in ranges:
        if _walk_range(buf, start, end, wanted_names, formats, ULog, subs, pos_of, dropouts) is None:
            return None
    return subs, pos_of, dropouts


def _walk_range(buf, pos, end, wanted_names, formats, ULog, subs, pos_of, dropouts):
    get = pos_of.get
    while pos + 3 <= end:
        nxt = pos + 3 + (buf[pos] | (buf[pos + 1] << 8))
        if nxt > end:
            break  # a message cut at the end of the file: pyulog stops there too
        typ = buf[pos + 2]
        if typ == _D:  # most messages: only the wanted ones are noted
            lst = get(buf[pos + 3] | (buf[pos + 4] << 8))
            if lst is not None:
                lst.append(pos)
            pos = nxt
            continue
        if typ == _A:
            name = buf[pos + 6: nxt].decode("utf-8", "replace").rstrip("\x00")
            if wanted_names is None or name in wanted_names:
                sub = ULog._MessageAddLogged(buf[pos + 3: nxt], None, formats)
                subs[sub.msg_id] = sub
                pos_of[sub.msg_id] = []
        elif typ == _O:
            dropouts.append(buf[pos + 3] | (buf[pos + 4] << 8))
        elif typ not in _KNOWN:
            return None
        pos = nxt
    return True


def read_topics(path, topics, ULog):
    """The topics' data (``topics`` None: every topic) as pyulog's ``data_list`` would hold them,
    plus the log's info and dropouts: ``(data_list, msg_info_dict, dropouts_ms,
    message_formats)``; None where only pyulog can read the log exactly."""
    head = ULog(str(path), message_name_filter_list=[], parse_header_only=True)
    if head.file_corruption:
        return None
    with open(path, "rb") as fh:
        buf = fh.read()
    offsets = list(getattr(head, "_appended_offsets", []) or []) if head.has_data_appended else []
    if any(not 16 <= o <= len(buf) for o in offsets) or offsets != sorted(offsets):
        return None
    edges = [16] + offsets + [len(buf)]
    ranges = list(zip(edges[:-1], edges[1:]))
    try:
        walked = _walk(buf, ranges, None if topics is None else set(topics), head.message_formats, ULog)
    except (KeyError, IndexError, ValueError):  # a format pyulog would have to judge
        return None
    if walked is None:
        return None
    subs, pos_of, dropouts = walked
    raw = np.frombuffer(buf, dtype=np.uint8)
    out = []
    for msg_id, sub in subs.items():
        pos = np.asarray(pos_of[msg_id], dtype=np.int64)
        if not pos.size:
            continue  # pyulog lists only topics with data
        n_item = sub.dtype.itemsize
        sizes = raw[pos].astype(np.int64) | (raw[pos + 1].astype(np.int64) << 8)
        if np.any(sizes - 2 < n_item) or np.any(sizes - 2 > sub.max_data_size):
            return None  # pyulog skips such messages as corrupt: let it
        rows = np.empty((len(pos), n_item), dtype=np.uint8)
        cols = np.arange(n_item, dtype=np.int64) + 5
        for a in range(0, len(pos), _CHUNK):  # gathered in chunks: the index array stays small
            rows[a:a + _CHUNK] = raw[pos[a:a + _CHUNK, None] + cols]
        arr = rows.view(sub.dtype).ravel()
        out.append(types.SimpleNamespace(name=sub.message_name, multi_id=sub.multi_id, msg_id=msg_id,
                                         data={k: arr[k] for k in arr.dtype.names}))
    return out, head.msg_info_dict, dropouts, head.message_formats
