"""Identity of a built FMU's runtime (the library's copy says: not a build).

``hammerbit fmu build`` replaces this file in the runtime package it ships.
``BUILD_HASH`` is the hash of the runtime sources; the package and the entry
module of the FMU are named by it, so builds of different code run side by
side in one Python process, and builds of the same code share one import.
The start values of a build are not code: they travel in the FMU's
``resources/start_values.json`` (:data:`START_VALUES_FILE`), read per instance.
"""

#: Hash of the runtime sources of this build; None in the library.
BUILD_HASH = None

#: File in the FMU's resources directory with {variable name: start value} of the build.
START_VALUES_FILE = "start_values.json"
