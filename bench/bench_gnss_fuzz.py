"""10^6 fuzzed valid-checksum sentences through the GNSS driver core; prints numbers.

gnss_driver.fuzz's seeded source replaces 1..3 fields of a sentence template (GGA, RMC, GST,
ZDA, VTG, HDT, GNS, GLL, GSA, PASHR PAT/ATT, LLQ) with special, random numeric or random text
values and frames it with a correct checksum; one valid epoch follows every 50 fuzzed
sentences. Fed in chunks of 1000 sentences with the receive time advancing at 115200 baud.
Printed: sentences and rate, exceptions caught in the core (must be 0), outputs and how many
broke the output invariants (``output_problems``: must be 0), rejected fields by kind.
"""

from __future__ import annotations

import sys
import time

from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.fuzz import TEMPLATES, FuzzSource, output_problems
from gnss_driver.reader import frame_sentence
from gnss_driver.solution import SolutionConfig

SENTENCES = 1_000_000
VALID_EVERY = 50
CHUNK = 1000
BAUD = 115200
LLQ_CRS = "EPSG:25832"  # LLQ grid positions on, so their fields are fuzzed too


def main(total: int = SENTENCES) -> int:
    source = FuzzSource(seed=13)
    valid = b"".join(frame_sentence(t) for t in TEMPLATES)
    driver = GnssDriver(DriverConfig(baud=BAUD, solution=SolutionConfig(llq_projection=LLQ_CRS)))
    now, outputs, bad_outputs = 1_700_000_000.0, 0, 0
    build_s = feed_s = 0.0
    for first in range(0, total, CHUNK):
        start = time.perf_counter()
        parts = []
        for k in range(first, min(first + CHUNK, total)):
            parts.append(source.sentence())
            if k % VALID_EVERY == VALID_EVERY - 1:
                parts.append(valid)
        chunk = b"".join(parts)
        build_s += time.perf_counter() - start
        now += len(chunk) * 10.0 / BAUD
        start = time.perf_counter()
        results = driver.feed(chunk, now) + driver.flush_idle(now + 1.0)
        feed_s += time.perf_counter() - start
        outputs += len(results)
        bad_outputs += sum(1 for out in results if output_problems(out))
    reader, fields = driver.reader.stats, driver.solver.fields
    print(
        f"fuzzed sentences {total:,} (+{total // VALID_EVERY:,} valid epochs):"
        f" {reader.sentences:,} parsed, {driver.solver.fields.bad_fields:,} fields rejected,"
        f" {fields.empty_fields:,} empty; reader rejected"
        f" {{{', '.join(f'{k}: {v:,}' for k, v in reader.rejected().items() if v)}}}"
    )
    print(
        f"core: {feed_s:.1f} s = {total / feed_s:,.0f} fuzzed sentences/s"
        f" (generating them {build_s:.1f} s); internal errors {driver.stats.internal_errors}"
        f" {driver.stats.last_internal_error}; outputs {outputs:,}, unsound {bad_outputs}"
    )
    top = ", ".join(f"{k} {v:,}" for k, v in fields.rejected.most_common(12))
    print(f"most rejected fields: {top}")
    return 1 if driver.stats.internal_errors or bad_outputs else 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else SENTENCES))
