//! OBJ meshes through `tobj`: positions, fan-triangulated faces in file order,
//! normals, texture coordinates and MTL diffuse colours and textures.
