"""``uvisi record``: check and export a priori feature records before uplink.

``uvisi record check FILE... [--strict]``
    validate a record TOML or an uplink words file (``.words``/any text: one 4-hex-digit word per
    line; ``.bin``/``.uplink``/``.dat``: big-endian binary) and print a verdict per file:
    ``OK``, ``OK with warnings`` or ``REJECTED`` with the reasons (wrong length, bad CRC, bad format
    id, unknown object type, undefined flag bits, non-normalised float, out-of-range values, units).
    Exit status 0 when every file passes, 1 when any is rejected (``--strict``: or has warnings).

``uvisi record export RECORD [--toml OUT.toml] [--words OUT.words|OUT.bin]``
    write a record (shipped name or TOML) as TOML and/or as its uplink image; both read back
    identically or nothing is claimed.
"""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("record", help="check / export a priori feature records (TOML, uplink words)",
                       description=__doc__.split("\n\n")[0])
    rs = p.add_subparsers(dest="record_command", metavar="RECORD_COMMAND")
    q = rs.add_parser("check", help="validate record files before uplink")
    q.add_argument("files", nargs="+", help="record TOML or uplink words files")
    q.add_argument("--strict", action="store_true", help="warnings also fail")
    q.set_defaults(func=_check)
    q = rs.add_parser("export", help="write a record as TOML and/or uplink words")
    q.add_argument("record", help="shipped record name or TOML file")
    q.add_argument("--toml", default=None, help="output TOML")
    q.add_argument("--words", default=None, help="output uplink image (.words text, .bin binary)")
    q.set_defaults(func=_export, outputs={"toml": "file", "words": "file"})
    p.set_defaults(func=lambda a: (p.print_help(), 0)[1])


def _check(args) -> int:
    from hil_harness.tuning.export import check_record_file
    bad = 0
    for f in args.files:
        res = check_record_file(f)
        for ln in res.lines():
            print(ln)
        if not res.ok or (args.strict and res.warnings):
            bad += 1
    n = len(args.files)
    print(f"{n - bad} of {n} file(s) pass" + (" (strict)" if args.strict else ""))
    return 1 if bad else 0


def _export(args) -> int:
    from hil_harness.tuning.export import record_from as load_record
    from hil_harness.tuning.export import export_record
    if not args.toml and not args.words:
        raise ValueError("give --toml and/or --words")
    rec = load_record(args.record)
    out = export_record(rec, args.toml, args.words, comment=f"record {rec.name}")
    print(f"record {rec.name!r} id {rec.record_id} version {rec.version}: uplink CRC {out['crc']}")
    print("wrote " + ", ".join(v for k, v in out.items() if k != "crc"))
    return 0
