-- Dataset jobs (`rtd datagen --database`): one task per generated scene, named by its index.
ALTER TABLE tasks ADD COLUMN scene BIGINT;
