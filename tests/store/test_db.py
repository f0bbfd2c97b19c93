"""Schema from migrations only, on the database of the run (SQLite files, or PostgreSQL)."""

from __future__ import annotations

from pathlib import Path

from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import inspect, text

from driftmap.config import Settings
from driftmap.store.schema import include_name, metadata
from driftmap.store.storage import Storage


class TestMigrations:
    def test_migrated_schema_matches_models(self, storage: Storage) -> None:
        with storage.db.engine.connect() as connection:
            diff = compare_metadata(
                MigrationContext.configure(connection, opts={"include_name": include_name}), metadata
            )
        assert diff == []

    def test_upgrade_twice_is_harmless(self, settings: Settings) -> None:
        Storage.open(settings).close()
        again = Storage.open(settings)
        tables = set(inspect(again.db.engine).get_table_names())
        again.close()
        assert {"sites", "survey_maps", "drives", "frames", "groundings", "alembic_version"} <= tables

    def test_sqlite_file_lives_under_data_dir_with_foreign_keys(self, tmp_path: Path) -> None:
        settings = Settings(data_dir=tmp_path / "data", database_url=None)  # the embedded default, always
        storage = Storage.open(settings)
        try:
            assert (settings.data_dir / "driftmap.sqlite3").is_file()
            with storage.db.engine.connect() as connection:
                assert connection.execute(text("PRAGMA foreign_keys")).scalar() == 1
        finally:
            storage.close()

    def test_database_url_overrides_the_embedded_default(self, tmp_path: Path) -> None:
        url = f"sqlite:///{tmp_path / 'elsewhere.db'}"
        settings = Settings(data_dir=tmp_path / "data", database_url=url)
        assert settings.resolved_database_url() == url
        Storage.open(settings).close()
        assert (tmp_path / "elsewhere.db").is_file()
