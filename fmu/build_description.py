"""sources/buildDescription.xml of the FMI 3.0 source FMU: how to compile the binary."""
from __future__ import annotations

from xml.sax.saxutils import quoteattr

from fmu.model_description import MODEL_NAME

#: File name and place of the build description inside the FMU.
BUILD_DESCRIPTION = "sources/buildDescription.xml"


def build_description_xml(source_files: list[str], model_name: str = MODEL_NAME) -> str:
    """Text of buildDescription.xml: one C99 build configuration of `source_files` (.c names in
    sources/) for the model identifier `model_name`, linked against libm; the include folder is sources/."""
    files = "\n".join(f"      <SourceFile name={quoteattr(name)}/>" for name in source_files)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiBuildDescription fmiVersion="3.0">
  <BuildConfiguration modelIdentifier="{model_name}"
    description="C99 sources; compile with the sources folder on the include path and link libm">
    <SourceFileSet language="C99">
{files}
    </SourceFileSet>
    <Library name="m" description="C math library (libm)"/>
  </BuildConfiguration>
</fmiBuildDescription>
"""
