"""XML from a user's file, parsed without entities or DTDs whatever its encoding, and to a
bounded depth: the SDF worlds' and URDF robots' parser.

Expat reads the file (it detects UTF-8, UTF-16 with or without a byte-order mark, and the
single-byte encodings an XML declaration may name; a multi-byte one such as Shift_JIS is
refused) and hands each piece to handlers that build an :mod:`xml.etree.ElementTree` tree as
``ElementTree.fromstring`` does. A document type
declaration, an entity declaration (general or parameter, internal or external) or a reference
to an external entity is refused by the handlers the moment Expat meets it, so nothing from the
file is ever expanded, in any encoding. (A byte search for ``<!ENTITY`` missed a UTF-16 file.)
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from xml.parsers import expat

MAX_DEPTH = 100
"""Deepest element nesting read (the root is depth 1); SDF worlds nest a few levels."""


class XmlRefused(ValueError):
    """The file is not XML bulletnav reads: malformed, a DTD or entity, or too deep. The message
    says which, with the line and column where Expat met it."""


def parse_xml(data: bytes, max_depth: int = MAX_DEPTH) -> ET.Element:
    """The root element of ``data`` (a whole XML document, as bytes).

    Raises:
        XmlRefused: malformed XML; a DOCTYPE, an entity declaration or an external entity
            reference; elements nested deeper than ``max_depth``.
    """
    parser = expat.ParserCreate(namespace_separator="}")
    builder = ET.TreeBuilder()
    depth = 0

    def where() -> str:
        return f"line {parser.CurrentLineNumber}, column {parser.CurrentColumnNumber + 1}"

    def refuse(what: str):
        def handler(*_args):
            raise XmlRefused(f"a {what} at {where()} is refused: bulletnav never expands entities from a "
                             "user's file (remove it)")
        return handler

    def name(tag: str) -> str:  # ElementTree's spelling of a namespaced name: {uri}local
        return "{" + tag if "}" in tag else tag

    def start(tag: str, attrs: dict[str, str]) -> None:
        nonlocal depth
        depth += 1
        if depth > max_depth:
            raise XmlRefused(f"elements nested more than {max_depth} deep (at {where()})")
        builder.start(name(tag), {name(k): v for k, v in attrs.items()})

    def end(tag: str) -> None:
        nonlocal depth
        depth -= 1
        builder.end(name(tag))

    parser.StartDoctypeDeclHandler = refuse("<!DOCTYPE> declaration")
    parser.EntityDeclHandler = refuse("<!ENTITY> declaration")
    parser.UnparsedEntityDeclHandler = refuse("<!ENTITY> declaration")
    parser.ExternalEntityRefHandler = refuse("reference to an external entity")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.buffer_text = True
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise XmlRefused(f"not well-formed XML ({expat.ErrorString(exc.code)}: line {exc.lineno}, "
                         f"column {exc.offset + 1})") from None
    except (ValueError, LookupError) as exc:  # an encoding Expat cannot read (multi-byte ones such as Shift_JIS)
        raise XmlRefused(f"an encoding bulletnav cannot read ({exc}); save it as UTF-8") from None
    return builder.close()


__all__ = ["MAX_DEPTH", "XmlRefused", "parse_xml"]
