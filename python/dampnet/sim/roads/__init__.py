"""Roads for the quarter-car loop and the IRI (ASTM E1926) of a profile.

  profiles.py  Road, impulse, bump, sine_sweep, iso8608 (A-H), thesis_rough_road, read_profile_csv
               (roads by name, as the command line and the sweep write them: dampnet.recipes.roads)
  iri.py       iri(): the Golden Car at 80 km/h, exact discretisation, per-segment values
"""

from dampnet.sim.roads.iri import IriResult, golden_car_response, iri
from dampnet.sim.roads.profiles import (ISO_BAND, ISO_CLASSES, Road, RoadError, RoadSample, bump, impulse,
                                    iso8608, iso_band_variance, iso_class_bounds, iso_psd,
                                    read_profile_csv, sine_sweep, sweep_frequency, thesis_rough_road)

__all__ = ["Road", "RoadError", "RoadSample", "impulse", "bump", "sine_sweep", "sweep_frequency",
           "iso8608", "iso_psd", "iso_band_variance", "iso_class_bounds", "ISO_CLASSES", "ISO_BAND",
           "thesis_rough_road", "read_profile_csv", "iri", "IriResult",
           "golden_car_response"]
