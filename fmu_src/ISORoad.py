"""ISORoad FMU: an ISO 8608 road profile (or a measured one) traversed at the input speed."""
from __future__ import annotations

from pathlib import Path

from plant import iso8608
from plant.iri import IRIMeter
from plant.road import MeasuredRoad, SyntheticRoad
from suspension_fmi.slave import ContractSlave


class ISORoad(ContractSlave):
    description = "ISO 8608 road source: elevation under the tyre as a function of travelled distance"
    state_attributes = ("road", "meter")

    def setup(self) -> None:
        if self.profile_file:
            path = Path(self.profile_file)
            if not path.is_absolute() and self.resources:
                # a bare name may refer to a file shipped in the FMU's resources
                shipped = Path(self.resources) / path
                path = shipped if shipped.is_file() else path
            self.road = MeasuredRoad.from_file(path, self.profile_units, self.profile_lateral_offset,
                                               self.profile_end)
        else:
            if not self.n_min < self.n_max:
                raise ValueError(f"n_min = {self.n_min!r} must be below n_max = {self.n_max!r}")
            gd = self.psd_n0 if self.psd_n0 > 0 else iso8608.class_psd_n0(self.road_class)
            self.road = SyntheticRoad(gd, self.waviness, self.n_min, self.n_max, self.seed)
        self.distance = 0.0
        self.meter = IRIMeter(self.iri_segment)
        self._output(self.vehicle_speed)

    def _output(self, speed: float) -> None:
        h, slope = self.road.eval(self.distance)
        self.road_height = h
        self.road_velocity = slope * speed
        self.iri = self.meter.update(self.distance, h)

    def step(self, t: float, h: float) -> None:
        speed = self.vehicle_speed
        self.distance += speed * h
        self._output(speed)
