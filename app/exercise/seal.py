"""The sealed answer key of a blind trial.

A blind trial's card (``trial.json``) carries its bone class sealed: the class is encrypted
with a keystream derived from a random nonce and authenticated by a tag that covers the
trial's **binding** (the exercise id, the trial's name and its plan's hash, which names the CT
series it was made on). Nothing in the token reads as a class: it is written in an alphabet
without the letter ``d`` (:data:`TOKEN_ALPHABET`), so neither ``D1``..``D4`` nor ``d1``..``d4``
can appear in it by chance. Copied onto another trial, or edited, it no longer opens
(:class:`SealError`). The seal keeps a trainee from reading the key by opening a file; it is not
a secret from someone who reads ctdrill's source (the instructor's plain key is the ``--key``
file of ``ctdrill exercise``).
"""

from __future__ import annotations

import hashlib
import hmac

from ctdrill.app.errors import AppInputError

#: The token's alphabet: 32 symbols, no ``d`` (nor ``i``, ``l``, ``o``).
TOKEN_ALPHABET = "0123456789abcefghjkmnpqrstuvwxyz"
_CONTEXT = b"ctdrill-trial-seal/1"
_NONCE_BYTES = 15
_TAG_BYTES = 15
_BODY_BYTES = 5
_TOKEN_BYTES = _NONCE_BYTES + _BODY_BYTES + _TAG_BYTES  # 35 bytes = 280 bits = 56 symbols


class SealError(AppInputError):
    """A sealed key that does not open for this trial (edited, or copied from another)."""


def _encode(raw: bytes) -> str:
    bits = int.from_bytes(raw, "big")
    n = len(raw) * 8 // 5
    return "".join(TOKEN_ALPHABET[(bits >> (5 * (n - 1 - k))) & 31] for k in range(n))


def _decode(token: str) -> bytes:
    bits = 0
    for ch in token:
        k = TOKEN_ALPHABET.find(ch)
        if k < 0:
            raise SealError(f"sealed key: {ch!r} is not a symbol of a sealed key")
        bits = (bits << 5) | k
    return bits.to_bytes(_TOKEN_BYTES, "big")


def _keys(nonce: bytes, binding: str) -> tuple[bytes, bytes]:
    base = hashlib.sha256(_CONTEXT + b"\0" + nonce + b"\0" + binding.encode("utf-8")).digest()
    stream = hashlib.sha256(b"stream\0" + base).digest()[:_BODY_BYTES]
    mac_key = hashlib.sha256(b"mac\0" + base).digest()
    return stream, mac_key


def seal(label: str, *, binding: str, nonce: bytes) -> str:
    """``label`` (1-5 ASCII characters, e.g. ``D3``) sealed to ``binding``.

    Parameters
    ----------
    label : the class.
    binding : what the key belongs to (:func:`trial_binding`).
    nonce : 15 bytes, different for every trial (random, or derived from the exercise's seed).
    """
    body = label.encode("ascii")
    if not 1 <= len(body) <= _BODY_BYTES or len(nonce) != _NONCE_BYTES:
        raise ValueError("seal: a label of 1-5 ASCII characters and a 15-byte nonce")
    stream, mac_key = _keys(nonce, binding)
    cipher = bytes(a ^ b for a, b in zip(body.ljust(_BODY_BYTES, b"\0"), stream, strict=True))
    tag = hmac.new(mac_key, nonce + cipher, hashlib.sha256).digest()[:_TAG_BYTES]
    return _encode(nonce + cipher + tag)


def unseal(token: str, *, binding: str) -> str:
    """The label sealed in ``token`` for ``binding``.

    Raises
    ------
    SealError
        Not a token, edited, or sealed for another binding (another trial).
    """
    if not isinstance(token, str) or len(token) != _TOKEN_BYTES * 8 // 5:
        raise SealError("sealed key: not a sealed key of ctdrill (wrong length)")
    raw = _decode(token)
    nonce, cipher, tag = (
        raw[:_NONCE_BYTES],
        raw[_NONCE_BYTES : _NONCE_BYTES + _BODY_BYTES],
        raw[_NONCE_BYTES + _BODY_BYTES :],
    )
    stream, mac_key = _keys(nonce, binding)
    want = hmac.new(mac_key, nonce + cipher, hashlib.sha256).digest()[:_TAG_BYTES]
    if not hmac.compare_digest(want, tag):
        raise SealError(
            "sealed key: it does not belong to this trial (edited, or copied from another "
            "trial); use the trial's own files as ctdrill exercise wrote them"
        )
    body = bytes(a ^ b for a, b in zip(cipher, stream, strict=True)).rstrip(b"\0")
    return body.decode("ascii")


def trial_binding(exercise_id: str, trial: str, plan_sha256: str) -> str:
    """What a trial's key is bound to: its exercise, its name and its plan's hash."""
    return f"{exercise_id}\0{trial}\0{plan_sha256}"


_BLOB_CONTEXT = b"ctdrill-trial-blob/1"


def _blob_keys(nonce: bytes, binding: str, n: int) -> tuple[bytes, bytes]:
    base = hashlib.sha256(_BLOB_CONTEXT + b"\0" + nonce + b"\0" + binding.encode("utf-8")).digest()
    stream = hashlib.shake_256(b"stream\0" + base).digest(n)
    return stream, hashlib.sha256(b"mac\0" + base).digest()


def seal_bytes(data: bytes, *, binding: str, nonce: bytes) -> str:
    """``data`` (any length) sealed to ``binding`` as :func:`seal` seals a class: encrypted
    with a keystream of the nonce and the binding, authenticated by a tag, written in
    :data:`TOKEN_ALPHABET` (no ``d``: no ``D1``..``D4`` by chance). A blind trial's session
    table (``table.json``) keeps its force table so: its values would give the bone away."""
    if len(nonce) != _NONCE_BYTES:
        raise ValueError("seal_bytes: a 15-byte nonce")
    stream, mac_key = _blob_keys(nonce, binding, len(data))
    cipher = bytes(a ^ b for a, b in zip(data, stream, strict=True))
    tag = hmac.new(mac_key, nonce + cipher, hashlib.sha256).digest()[:_TAG_BYTES]
    raw = nonce + tag + cipher
    raw += b"\0" * (-len(raw) % 5)  # whole 40-bit groups: 8 symbols each
    return f"{len(data)}:" + "".join(_encode(raw[i : i + 5]) for i in range(0, len(raw), 5))


def unseal_bytes(token: str, *, binding: str) -> bytes:
    """The bytes :func:`seal_bytes` sealed in ``token`` for ``binding``.

    Raises
    ------
    SealError
        Not such a token, edited, or sealed for another binding (another trial).
    """
    size_text, _, body = token.partition(":") if isinstance(token, str) else ("", "", "")
    if not size_text.isdigit() or len(body) % 8 or not body:
        raise SealError("sealed data: not data sealed by ctdrill")
    size = int(size_text)
    groups = bytearray()
    for i in range(0, len(body), 8):  # 8 symbols, 5 bytes
        bits = 0
        for ch in body[i : i + 8]:
            k = TOKEN_ALPHABET.find(ch)
            if k < 0:
                raise SealError(f"sealed data: {ch!r} is not a symbol of sealed data")
            bits = (bits << 5) | k
        groups += bits.to_bytes(5, "big")
    raw = bytes(groups)
    head = _NONCE_BYTES + _TAG_BYTES
    if len(raw) < head + size or any(raw[head + size :]):
        raise SealError("sealed data: its length does not match its contents")
    nonce, tag, cipher = raw[:_NONCE_BYTES], raw[_NONCE_BYTES:head], raw[head : head + size]
    stream, mac_key = _blob_keys(nonce, binding, size)
    want = hmac.new(mac_key, nonce + cipher, hashlib.sha256).digest()[:_TAG_BYTES]
    if not hmac.compare_digest(want, tag):
        raise SealError(
            "sealed data: it does not belong to this trial (edited, or copied from another "
            "trial); use the session's files as ctdrill rehearse wrote them"
        )
    return bytes(a ^ b for a, b in zip(cipher, stream, strict=True))
