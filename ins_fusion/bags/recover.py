"""Recover the bag of a recording that did not finish (killed, power cut, full disk).

``BagWriter`` leaves on disk: the closed split files ``NAME/NAME_<i>.<ext>`` (complete), the file
being written in its own directory ``NAME/NAME_<k>/NAME_<k>.<ext>``, and no ``metadata.yaml``.
``recover_bag`` takes every message ``salvage`` finds in each of them, in log-time order, into a
new bag with one file per recovered file. The new bag is written under a temporary name beside
the output and renamed when it is complete: a bag under the final name is always whole.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ins_fusion.bags.bag_io import BagError, BagWriter
from ins_fusion.bags.output import refuse_existing, whole_bag
from ins_fusion.bags.resume import split_name
from ins_fusion.bags.salvage import STORAGE_OF_SUFFIX, Salvaged, salvage
from ins_fusion.bags.summary import BagSummary


@dataclass(frozen=True)
class Recovered:
    """What ``recover_bag`` did: what each input file held, the summary of the new bag."""

    files: list[Salvaged]
    summary: BagSummary
    #: topics left out because their type is not in the Jazzy typestore: topic -> type
    skipped: dict[str, str]

    @property
    def last_write_ns(self) -> int:
        """When the recording last wrote to its files: no earlier than its last message."""
        return max((f.last_write_ns for f in self.files), default=0)

    def end_losses_s(self) -> dict[str, float]:
        """Per topic, the seconds between its last recovered message and the last write of the
        recording: at most what was lost of it at the end (0 when its last message is later)."""
        return {
            topic: max(0.0, (self.last_write_ns - stats.last_ns) / 1e9)
            for topic, stats in self.summary.topics.items()
        }

    def format(self, title: str) -> str:
        """Per file what was kept and dropped, then per topic what may be missing at the end."""
        lines = [title]
        for found in self.files:
            text = f"  {found.path.name}: {len(found.messages)} messages"
            if found.dropped_bytes:
                text += f", {found.dropped_bytes} bytes at the end dropped (incomplete)"
            if found.stopped:
                text += f"; reading stopped at: {found.stopped}"
            lines.append(text)
        lines.extend(
            f"  {t} [{m}] not recovered: type unknown here" for t, m in self.skipped.items()
        )
        lines.append(self.summary.format())
        losses = self.end_losses_s()
        if losses:
            lines.append("  time before the recording's last write with no message (lost at most):")
            lines.extend(f"    {topic}: {losses[topic]:.3f} s" for topic in sorted(losses))
        return "\n".join(lines)


def storage_files_left(bag: Path) -> list[Path]:
    """The storage files an unfinished recording left in ``bag``, in split order: named after
    ``bag``, or after the one name they share (a recording copied under another name)."""
    found = {
        path: split
        for path in [*bag.glob("*.*"), *bag.glob("*/*.*")]
        if (split := split_name(path.name)) is not None
    }
    names = {name for name, _ in found.values()}
    if len(names) > 1 and bag.name not in names:
        raise BagError(f"{bag}: storage files of several recordings: {', '.join(sorted(names))}")
    name = bag.name if bag.name in names else next(iter(names), bag.name)
    return [path for path, split in sorted(found.items(), key=lambda f: f[1]) if split[0] == name]


def recover_bag(bag: Path, output: Path) -> Recovered:
    """Write every message the unfinished recording ``bag`` holds into the new bag ``output``
    (same storage). ``bag`` is only read. BagError if it is complete, holds nothing, or
    ``output`` exists."""
    if (bag / "metadata.yaml").exists():
        raise BagError(f"{bag} has its metadata.yaml: complete, nothing to recover")
    refuse_existing(output)
    sources = storage_files_left(bag)
    if not sources:
        raise BagError(f"{bag}: no NAME_<n>.mcap or .db3 file to recover")
    storages = {STORAGE_OF_SUFFIX[f.suffix] for f in sources}
    if len(storages) > 1:
        raise BagError(f"{bag}: both MCAP and sqlite3 files; move one kind away")
    with whole_bag(output, "recovering") as path:
        found: list[Salvaged] = []
        skipped: dict[str, str] = {}
        with BagWriter(path, storage=storages.pop()) as writer:
            for source in sources:
                found.append(salvaged := salvage(source))
                if salvaged.messages:
                    skipped.update(writer.write_salvaged(salvaged))
                    writer.start_new_file()
        if not writer.summary.count:
            raise BagError(f"{bag}: no complete message in {', '.join(f.name for f in sources)}")
    return Recovered(found, writer.summary, skipped)
