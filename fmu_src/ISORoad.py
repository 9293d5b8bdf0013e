"""ISORoad FMU: an ISO 8608 road profile (or a measured one) traversed at the input speed, under
the front tyre and, ``wheelbase`` behind it, under the rear tyre."""
from __future__ import annotations

from pathlib import Path

from suspension_estimation.plant import iso8608
from suspension_estimation.plant.iri import IRIMeter
from suspension_estimation.plant.road import MeasuredRoad, SyntheticRoad
from suspension_estimation.plant.state_classes import ISO_ROAD_STATE
from suspension_estimation.suspension_fmi.slave import ContractSlave


class ISORoad(ContractSlave):
    description = "ISO 8608 road source: elevation under the tyre as a function of travelled distance"
    state_attributes = ("road", "meter")
    state_classes = ISO_ROAD_STATE
    derived_attributes = ("road",)  # a function of the parameters; the run's position is `distance`

    def setup(self) -> None:
        if self.profile_file:
            self.road = MeasuredRoad.from_file(self._profile_path(), self.profile_units,
                                               self.profile_lateral_offset, self.profile_end)
        else:
            if not self.n_min < self.n_max:
                raise ValueError(f"n_min = {self.n_min!r} must be below n_max = {self.n_max!r}")
            gd = self.psd_n0 if self.psd_n0 > 0 else iso8608.class_psd_n0(self.road_class)
            self.road = SyntheticRoad(gd, self.waviness, self.n_min, self.n_max, self.seed)
        self.distance = 0.0
        self.meter = IRIMeter(self.iri_segment)
        self._output(self.vehicle_speed)

    def _profile_path(self) -> Path:
        """profile_file as given when absolute; a relative one names a file shipped in the FMU's
        resources folder (the master's working directory is not looked at: it differs between
        masters)."""
        path = Path(self.profile_file)
        if path.is_absolute():
            return path
        shipped = Path(self.resources) / path if self.resources else None
        if shipped is not None and shipped.is_file():
            return shipped
        tried = f"'{shipped}' does not exist" if shipped is not None else "the FMU has no resources folder"
        raise ValueError(f"profile_file = '{self.profile_file}' is a relative path, which names a file in the "
                         f"FMU's resources folder, and {tried}: give an absolute path")

    def _output(self, speed: float) -> None:
        h, slope = self.road.eval(self.distance)
        self.road_height = h
        self.road_velocity = slope * speed
        self.road_height_rear = self.road.eval(self.distance - self.wheelbase)[0] if self.wheelbase > 0 else h
        self.iri = self.meter.update(self.distance, h)

    def step(self, t: float, h: float) -> None:
        speed = self.vehicle_speed
        self.distance += speed * h
        self._output(speed)
