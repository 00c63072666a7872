"""Untrusted ``.jxm`` input: the fuzz suite (fast part by default, 2 500 cases under -m slow)
and one test per defect class a codec audit found."""

from __future__ import annotations

import lzma
import subprocess
import sys

import pytest

import harness
import jxm
from jaxmesh.compress import codec as C

RSS_PROBE = """
import resource, subprocess, sys
p = subprocess.run(sys.argv[1:], capture_output=True, text=True)
print(p.returncode)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
print(p.stderr)
"""


def _check(results, n):
    assert len(results) == n
    counts = harness.summary(results)
    assert not harness.bad(results), harness.bad(results)[:5]
    assert counts["error"] > n // 2  # the mutations reach the decoder's checks
    return counts


def test_fuzz_jxm_fast():
    _check(harness.run("jxm", range(300), timeout_s=10), 300)


@pytest.mark.slow
def test_fuzz_jxm_2500():
    counts = _check(harness.run("jxm", range(2500), timeout_s=10), 2500)
    print(counts)


@pytest.fixture(scope="module")
def sphere_file():
    import jaxmesh

    v, f = jxm._sphere()
    return C.compress(jaxmesh.Mesh.from_arrays(v, f), keep=0.5, bits=10).data


def _forge(data, *, field=None, value=None, section=None, payload=None, word=None):
    fields, secs = jxm._sections(data)
    fields = list(fields)
    if field is not None:
        fields[field] = value
    if section is not None:
        secs[section] = bytearray(payload)
    if word is not None:
        off, val = word
        secs[0][off:off + 4] = val.to_bytes(4, "little")
    return jxm._pack(fields, secs)


def _ranks_block(ranks):
    from jaxmesh.compress.coefficients import encode_ranks

    return encode_ranks(ranks)


CLAIMS = {
    "header vertices": dict(field=3, value=2**31),
    "header faces": dict(field=4, value=2**31),
    "header patches": dict(field=5, value=2**31),
    "connectivity vertices": dict(word=(8, 2**31)),
    "connectivity faces": dict(word=(12, 2**31)),
    "vertex copies": dict(word=(0, 2**31)),
    "patch rank": dict(section=2, payload=b""),  # filled in below
}


# one fresh process per claim (and one per worker for the baseline): two claims (a header count, an
# inner count) in the default run, the other five in the slow pass; test_fuzz_jxm_fast forges such
# counts in-process too
DEFAULT_CLAIMS = ("header vertices", "patch rank")


@pytest.fixture(scope="module")
def import_rss_kb() -> int:
    """The peak RSS (kB) of a fresh process that imports the decompress command (the command
    line imports only the command it runs): the baseline of every claim."""
    probe = subprocess.run([sys.executable, "-c", RSS_PROBE, sys.executable, "-c", "import jaxmesh.cli.decompress"],
                           capture_output=True, text=True, timeout=120)
    return int(probe.stdout.split("\n")[1])


@pytest.mark.parametrize("claim", [c if c in DEFAULT_CLAIMS else pytest.param(c, marks=pytest.mark.slow)
                                   for c in sorted(CLAIMS)])
def test_claims_of_2_31_elements_are_refused_in_bounded_memory(tmp_path, sphere_file, import_rss_kb, claim):
    kw = dict(CLAIMS[claim])
    if claim == "patch rank":
        kw["payload"] = _ranks_block([2**31])
    src = tmp_path / "evil.jxm"
    src.write_bytes(_forge(sphere_file, **kw))
    probe = subprocess.run([sys.executable, "-c", RSS_PROBE, sys.executable, "-m", "jaxmesh.cli", "decompress",
                            str(src), str(tmp_path / "out.ply")], capture_output=True, text=True, timeout=120)
    code, rss_kb, err = probe.stdout.split("\n", 2)
    err = err.rstrip("\n")
    assert code == "1" and err.startswith("jaxmesh: error: ") and "\n" not in err, err
    assert "corrupt" in err or "invalid" in err
    # what decoding adds to the process's import (JAX and scipy: 188 MB in the dev venv, 205 MB in a
    # fresh one; the whole process peaked at 189.5 MB and 207 MB): a hostile file costs almost nothing
    assert int(rss_kb) < import_rss_kb + 25 * 1024
    assert not (tmp_path / "out.ply").exists()


def test_lzma_bomb_in_the_order_section_is_refused_without_inflating(sphere_file):
    bomb = lzma.compress(b"\0" * (16 * 2**20))
    forged = _forge(sphere_file, field=2, value=4, section=4, payload=bomb)
    with pytest.raises(C.CodecError, match="does not match the header's digest"):       # caught before inflating
        C.decompress(forged)
    with pytest.raises(C.CodecError, match="cannot hold|does not inflate"):     # and so with the digest forged too
        C.decompress(jxm.redigest(forged))


def test_fallback_block_inflates_at_most_what_it_announces():
    from jaxmesh.compress import connectivity as K

    payload = lzma.compress(b"\0" * (10 * 2**20))
    block = (4).to_bytes(4, "little") + (1).to_bytes(4, "little") + payload
    with pytest.raises(K.ConnectivityError, match="does not inflate to the announced 24 bytes"):
        K.fallback_decode(block)


@pytest.mark.parametrize("field,value,match", [
    (8, float("nan"), "quantization step"),
    (8, float("inf"), "quantization step"),
    (8, -1.0, "quantization step"),
    (9, float("nan"), "non-finite reconstruction check"),
    (7, float("nan"), "kept fraction"),
    (6, 0, "quantization bits"),
])
def test_non_finite_or_impossible_header_numbers_are_codec_errors(sphere_file, field, value, match):
    with pytest.raises(C.CodecError, match=match):
        C.decompress(_forge(sphere_file, field=field, value=value))


def test_a_nan_check_no_longer_disables_the_reconstruction_check(sphere_file):
    """Before: |Σ g v̂ − NaN| > tol is False, so any geometry passed."""
    fields, secs = jxm._sections(sphere_file)
    coef = bytearray(secs[3])
    coef[len(coef) // 2] ^= 0x10  # different coefficients...
    forged = _forge(sphere_file, section=3, payload=coef)
    with pytest.raises(C.CodecError, match="coefficient section"):
        C.decompress(forged)
    fields = list(fields)
    fields[9:12] = [float("nan")] * 3  # ...and a NaN check that used to wave them through
    with pytest.raises(C.CodecError, match="non-finite"):
        C.decompress(jxm._pack(fields, [*secs[:3], coef, secs[4]]))
